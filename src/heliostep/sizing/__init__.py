"""`heliostep size`: the smallest catalogue drive that holds a scenario's load, its plan, verdict and sheet."""
