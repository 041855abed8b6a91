"""What the command line shows while it works: progress on standard error.

On a terminal a command shows a tqdm bar that names the latest frame (index, type, bytes,
PSNR when known) beside tqdm's rate and time left. Anywhere else (a pipe, a log file, CI)
it writes one plain line per frame instead, so that a log shows what was done and how
long is left without carriage returns; ``-q`` silences both.

Imported by every command: it imports nothing beyond the standard library, and tqdm only
when a bar is shown.
"""

from __future__ import annotations

import os
import sys
import threading
import time

#: Seconds between the lines a phase without per-item lines (reading the input) writes
#: when standard error is not a terminal: a sign of life on long inputs, silence on short ones.
QUIET_PHASE_INTERVAL = 10.0


def is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal a bar can be drawn on: one with columns (a pseudo
    terminal whose size nobody set has none, and tqdm would draw nothing there)."""
    try:
        return stream.isatty() and os.get_terminal_size(stream.fileno()).columns > 0
    except (AttributeError, ValueError, OSError):  # no isatty or fileno, or a closed stream
        return False


class Progress:
    """Progress of ``total`` items of one phase of a command (a context manager).

    ``step(text)`` counts an item done; ``text`` names it and its figures ("frame 3: P,
    864 bytes"). ``note(text)`` shows a state on the bar without counting (nothing in
    lines). Modes: ``"bar"`` (a terminal), ``"lines"`` (one line per item, with the time
    left), ``"off"`` (``-q``), or ``"sparse"``: as ``"lines"``, but at most one line per
    ``QUIET_PHASE_INTERVAL`` seconds, for a phase whose items are not what the user
    waits for (reading the frames before encoding them).
    """

    def __init__(self, total: int, desc: str, *, command: str, quiet: bool, unit: str = "frame",
                 per_item_lines: bool = True, stream=None):
        self.total, self.desc, self.unit, self.command = total, desc, unit, command
        self.stream = sys.stderr if stream is None else stream
        if quiet:
            self.mode = "off"
        elif is_terminal(self.stream):
            self.mode = "bar"
        else:
            self.mode = "lines" if per_item_lines else "sparse"
        self.done = 0
        self._lock = threading.Lock()  # the core's decoder reports frames from its threads
        self._start = self._last_line = time.perf_counter()
        self._bar = None
        if self.mode == "bar":
            from tqdm import tqdm  # a fifth of a second to import: only commands that show a bar pay it

            # Each frame of a phase with per-item lines is worth showing: it names the frame.
            every = {"mininterval": 0, "miniters": 1} if per_item_lines else {}
            self._bar = tqdm(total=total, desc=desc, unit=unit, file=self.stream, leave=False, disable=False, **every)

    @property
    def off(self) -> bool:
        return self.mode == "off"

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        if self._bar is not None:
            self._bar.close()

    def step(self, text: str | None = None) -> None:
        """One more item done; ``text`` describes it (None: only counted)."""
        with self._lock:
            self._step(text)

    def _step(self, text: str | None) -> None:
        self.done += 1
        if self.mode == "bar":
            if text:
                self._bar.set_postfix_str(text, refresh=False)
            self._bar.update()
        elif self.mode == "lines":
            self._line(text)
        elif self.mode == "sparse":
            now = time.perf_counter()
            if now - self._last_line >= QUIET_PHASE_INTERVAL and self.done < self.total:
                self._line(text)

    def note(self, text: str) -> None:
        """A state to show on the bar (which runs are running), without counting."""
        if self._bar is not None:
            self._bar.set_postfix_str(text)

    def _line(self, text: str | None) -> None:
        self._last_line = now = time.perf_counter()
        left, seconds = "", (now - self._start) / self.done * (self.total - self.done)
        if seconds >= 1:
            left = f", about {duration(seconds)} left"
        what = f": {text}" if text else ""
        print(f"dynmesh {self.command}: {self.desc} {self.done}/{self.total}{what}{left}", file=self.stream, flush=True)


def duration(seconds: float) -> str:
    """A time span in words a log reader takes in at once: "0.4 s", "12 s", "3 min 05 s"."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def frame_text(index: int, stats: dict) -> str:
    """A coded frame in a few words: "frame 3: P, 864 bytes, 0.14 s", with its PSNR when the
    encoder measured one."""
    kind = stats.get("type")
    parts = [str(getattr(kind, "value", kind))] if kind is not None else []
    if "bytes" in stats:
        parts.append(f"{stats['bytes']} bytes")
    psnr = stats.get("d1_psnr", stats.get("psnr"))
    if psnr is not None:
        parts.append(f"D1 {psnr:.2f} dB")
    if "seconds" in stats:
        parts.append(f"{stats['seconds']:.2f} s")
    return f"frame {index}" + (": " + ", ".join(parts) if parts else "")


def metrics_text(index: int, figures: dict) -> str:
    """A measured frame: "frame 3: D1 62.10 dB, D2 66.31 dB" (and Y when textured)."""
    parts = [f"D1 {figures['d1_psnr']:.2f} dB", f"D2 {figures['d2_psnr']:.2f} dB"]
    if "y_psnr" in figures:
        parts.append(f"Y {figures['y_psnr']:.2f} dB")
    return f"frame {index}: " + ", ".join(parts)


def run_text(run_id: str, record: dict, reused: bool) -> str:
    """An evaluation run done: "wobbly/dynmesh/qp26: 12345 bytes, D1 62.10 dB (measured)"."""
    parts = []
    if "bytes" in record:
        parts.append(f"{record['bytes']} bytes")
    if record.get("d1_psnr") is not None:
        parts.append(f"D1 {record['d1_psnr']:.2f} dB")
    return f"{run_id}: " + ", ".join(parts) + (" (saved result reused)" if reused else " (measured)")


def table(rows: list[dict], columns: list[tuple[str, str, str]]) -> str:
    """Fixed-width table; columns are (key, heading, format)."""
    cells = [[format(r[k], f) for k, _, f in columns] for r in rows]
    widths = [max([len(h)] + [len(c[i]) for c in cells]) for i, (_, h, _) in enumerate(columns)]
    line = lambda vals: "  ".join(v.rjust(w) for v, w in zip(vals, widths))
    return "\n".join([line([h for _, h, _ in columns])] + [line(c) for c in cells])
