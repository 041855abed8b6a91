"""Synthetic mesh sequences, made with numpy alone: metaballs that merge and split, polygonized
anew every frame (``metaballs``: the sequence of ``dynmesh synth``, ``dynmesh demo``, the
conformance vectors and most tests), and two toothed gears turning rigidly, resampled every
frame (``gears``: the hard case of the anchor's rigid alignment, ``tests/test_inter.py``).

Two more re-mesh every frame, as a capture does, the union of parts that touch into ONE
connected surface whose parts move differently, so that connected components are not parts:
two meshing gears turning in opposite directions with fused teeth (``fused_gears``; a positive
``gap`` parts them into two components), and a wrinkled sleeve sliding along an arm it rests on
(``cloth``). Both change grid resolution, so vertex count and connectivity, every frame.
"""

from __future__ import annotations

from .cloth import cloth_sequence
from .fused_gears import fused_gear_sequence
from .gears import gear_sequence
from .metaballs import polygonize, synth_sequence, write_sequence

__all__ = ["cloth_sequence", "fused_gear_sequence", "gear_sequence", "polygonize", "synth_sequence", "write_sequence"]
