"""Synthetic mesh sequences, made with numpy alone: metaballs that merge and split, polygonized
anew every frame (``metaballs``: the sequence of ``dynmesh synth``, ``dynmesh demo``, the
conformance vectors and most tests), and two toothed gears turning rigidly, resampled every
frame (``gears``: the hard case of the anchor's rigid alignment, ``tests/test_inter.py``).
"""

from __future__ import annotations

from .gears import gear_sequence
from .metaballs import polygonize, synth_sequence, write_sequence

__all__ = ["gear_sequence", "polygonize", "synth_sequence", "write_sequence"]
