"""Textures, orchestrated here and computed per texel in the core: the texture stage per
group of frames and the texture unit's layout (``coder``: ``TextureEncoder``,
``TextureDecoder``, ``pack_group``, ``unpack_group``), the UV atlas of a group's intra frame
(``atlas``, xatlas) and the group's images as one video (``video``, PyAV). xatlas and PyAV are
imported by the functions that use them, so importing this package costs neither.
"""

from __future__ import annotations

from . import atlas, video
from .coder import (TEXTURE_DEFAULTS, GroupHeader, TextureDecoder, TextureEncoder, atlas_size_for, check_options,
                    pack_group, resolve_options, texture_qp_for, unpack_group)

__all__ = ["TEXTURE_DEFAULTS", "GroupHeader", "TextureDecoder", "TextureEncoder", "atlas", "atlas_size_for", "check_options", "resolve_options", "texture_qp_for",
           "pack_group", "unpack_group", "video"]
