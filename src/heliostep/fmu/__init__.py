"""Modelica models -> FMI 2.0 (or 3.0) Model Exchange FMUs, built on first use and cached by content.

:mod:`~heliostep.fmu.modelica` (pymoca front end), :mod:`~heliostep.fmu.export` (CasADi code
generation, modelDescription, gcc, zip), ``c/fmi2_model_exchange.c`` and
``c/fmi3_model_exchange.c`` (each FMI version's signatures, compiled with every model, around the
entry points' bodies in ``c/model_exchange_core.h``), :mod:`~heliostep.fmu.build` (the content-keyed cache) and
:mod:`~heliostep.fmu.reference` (variant name or path). Imports nothing of heliostep but
:mod:`heliostep.errors`, :mod:`heliostep.paths` and :mod:`heliostep.toolchain`.
"""
