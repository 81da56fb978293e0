"""Modelica models -> FMI 2.0 (or 3.0) Model Exchange FMUs, built on first use and cached by content.

Imports nothing of heliostep but :mod:`heliostep.errors`, :mod:`heliostep.paths` and
:mod:`heliostep.toolchain` (docs/fmus.md, docs/architecture.md).
"""
