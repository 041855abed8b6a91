"""Measuring the codec, behind ``dynmesh eval``: rate-distortion experiments from TOML files,
cached and resumable (``evaluate``), the codecs measured beside dynmesh (``baselines``: Draco
through DracoPy) and what the results say (``report``: BD-rates, RD plots with matplotlib, the
Markdown page). DracoPy and matplotlib are the ``dynmesh[eval]`` extra: they are imported by
the functions that use them, so every module here imports without them. This file imports
nothing: import the module you use (``dynmesh demo`` takes ``report.bd_rate`` alone, without
``evaluate``, which hashes the compiled core when it is imported).
"""
