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

#: The quantization parameters the encoder accepts, first and last.
QP_RANGE: tuple[int, int] = tuple(_core.QP_RANGE)


def base_ratio_rule() -> str:
    """The encoder's base mesh ratio as a function of QP (``base_ratio`` None), in words:
    read from the core, so that ``--help`` cannot drift from what the encoder does."""
    first, last = QP_RANGE
    runs: list[list] = []  # [ratio, first qp, last qp]
    for qp in range(first, last + 1):
        ratio = _core.base_ratio_for_qp(qp)
        if runs and runs[-1][0] == ratio:
            runs[-1][2] = qp
        else:
            runs.append([ratio, qp, qp])
    if len(runs) == 1:
        return f"{runs[0][0]:g} at every QP"
    words = [f"{runs[0][0]:g} up to QP {runs[0][2]}"]
    words += [f"{ratio:g} to {end}" for ratio, _, end in runs[1:-1]]
    words.append(f"{runs[-1][0]:g} from {runs[-1][1]}")
    return ", ".join(words)


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
#: None leaves the option to the encoder: the atlas side from the source textures' texel
#: count, the texture QP from the geometry QP (``texture.resolve_options``). AV1 by default:
#: browsers decode it (the player plays it textured), and at the same luma PSNR it takes
#: 12-25 % fewer bytes than libx265 ultrafast (``texture/video.py``).
TEXTURE: dict = {"texture_size": None, "texture_qp": None, "texture_codec": "av1"}

#: Texture video codec names as the stream signals them (the index is the code), as the
#: core's texture unit syntax lists them.
TEXTURE_CODECS: tuple[str, ...] = tuple(_core.TEXTURE_CODECS)


#: ``texture_qp_for``: texture QP = slope x geometry QP + offset. Of the mappings with slopes
#: 0.5-1.5 over (geometry QP 20-36, texture QP 20-46) pairs of the shared textured captures
#: (``experiments/texture_qp_hull.py``, AV1), this one has the best worse-of-D1-and-Y total-rate
#: BD-rate against the test model's all-intra points (basketball_textured D1 -43.3 %, Y -37.0 %;
#: liam_textured D1 -62.7 %, Y -47.2 %; the next, texture QP = QP + 8: -35.5 / -37.3 and
#: -59.5 / -47.9 %).
TEXTURE_QP_SLOPE: float = 0.75
TEXTURE_QP_OFFSET: float = 17.0


def texture_qp_for(qp: int) -> int:
    """The texture video QP that goes with the geometry QP ``qp`` when ``texture_qp`` is not
    given, so that one knob moves geometry and texture together along the joint
    rate-distortion curve."""
    return int(min(51, max(0, round(TEXTURE_QP_SLOPE * qp + TEXTURE_QP_OFFSET))))


def texture_qp_rule() -> str:
    """``texture_qp_for`` in words, for ``--help``."""
    return f"{TEXTURE_QP_SLOPE:g} x QP + {TEXTURE_QP_OFFSET:g}: QP 20, 28, 36 give " + \
        ", ".join(str(texture_qp_for(q)) for q in (20, 28, 36))
