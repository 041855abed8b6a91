"""What the layers above the core add to its errors without changing their class."""

from __future__ import annotations


def with_frame(e: ValueError, frame: int, after: str = "") -> ValueError:
    """``e`` again, of the same class (``InputError``, ``DecodeError``, ``UnsupportedError``
    or a plain ValueError), its message naming ``frame`` first and ending with ``after``; a
    ``DecodeError``'s frame and byte offset (its further args) are kept."""
    message = e.args[0] if e.args else str(e)
    return type(e)(f"frame {frame}: {message}{after}", *e.args[1:])
