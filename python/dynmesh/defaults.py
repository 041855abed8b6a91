"""Option defaults and the frame type, importable without numpy: the command line's parser
needs them for every command, and ``dynmesh decode`` should not pay for the modules that use
them."""

from __future__ import annotations

from enum import StrEnum

from . import _core

#: Encoder defaults, as the Rust core defines them; ``dynmesh encode --help`` documents each.
ENCODER: dict = dict(_core.default_options())

#: The values of the ``inter`` option ("none", then the anchor's stages) and of ``lifting``.
INTER_MODES: tuple = tuple(_core.INTER_MODES)
LIFTINGS: tuple = tuple(_core.LIFTINGS)

class FrameType(StrEnum):
    """A frame's type as the encoder's statistics and ``info`` give it: a string ("I", "P")
    in JSON output and tables, compared by name in code."""

    INTRA = "I"
    PREDICTED = "P"
    #: A damaged frame unit, whose type cannot be read (``info`` of a damaged stream).
    UNKNOWN = "?"


#: The most recent frames a predicted frame may try as its reference (``references``).
MAX_REFERENCES: int = _core.MAX_REFERENCES

#: Defaults of the texture options (``encode_frames`` takes them beside the geometry ones).
TEXTURE: dict = {"texture_size": 2048, "texture_qp": 32, "texture_codec": "hevc"}

#: Texture video codec names as the stream signals them (the index is the code).
TEXTURE_CODECS = ("hevc", "av1")
