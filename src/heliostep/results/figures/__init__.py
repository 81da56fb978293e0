"""The figures of a run, computed from every solution row (`solution`, `steps`), typed (`run_summary`) and
gathered into `summary.json` (`run_figures`, `summary`, `stow`, `tradeoffs`)."""
