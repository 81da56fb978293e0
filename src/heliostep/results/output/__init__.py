"""A command's output folder: names and atomic writes (`files`), its lock, manifest and swap (`folder`), a run's
records (`run_files`) and the rescue after a full disk (`rescue`)."""
