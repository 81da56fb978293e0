"""Light on the tube: over a run (`on_tube`, between the rows `rows`), one mirror's power (`mirror_power`), the
field's year (`field`)."""
