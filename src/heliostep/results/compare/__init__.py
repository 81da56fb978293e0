"""A trace against a reference: tolerance tubes (`tolerance`, `tube`, `traces`), signal mapping, CI verdicts
and regression."""
