"""Rate-distortion experiments: a TOML file in, one measured record per run out.

An experiment is sequences x codec variants x rate points. Each *run* (one sequence,
one variant, one rate point) encodes the sequence, decodes it, and measures D1/D2 PSNR
per frame as DESIGN.md section 3 says (``dynmesh.metrics``: grid over the bounding box
of the source frames of the run, the sequence's peak), the stream size and the encode
and decode wall time.

The experiment file (paths are relative to the file's directory)::

    anchor = "dynmesh-ai"     # BD-rates are measured against this variant (default: the first)
    baselines = ["draco"]     # optional: further reference variants, a BD-rate table each
    fps = 30                  # optional: frames per second for Mbit/s (default 30)
    grid_size = 1024          # optional: metric sampling grid (default 1024)

    [[sequences]]
    name = "basketball_player"
    path = "../data/basketball_player"  # directory, glob or printf pattern
    start = 0                           # optional: first frame (index; number for printf)
    count = 10                          # optional: number of frames (default: all)
    peak = 18.75                        # optional: PSNR peak (default: largest box side)
    fps = 30                            # optional: this sequence's frame rate (default: the top-level fps)

    [rates.dynmesh]                     # a named set of rate points, shared by name
    R1 = { qp = 46, base_ratio = 0.0078125, bits = 9 }
    R2 = { qp = 40, base_ratio = 0.015625, bits = 10 }

    [[variants]]
    name = "dynmesh-ai"
    codec = "dynmesh"                   # "dynmesh" or "draco"
    options = { subdiv = 3 }            # optional: options of every rate point
    rates = "dynmesh"                   # a [rates.NAME] set ...

    [[variants]]
    name = "draco"
    codec = "draco"
    [variants.rates]                    # ... or the variant's own rate points
    R1 = { quantization_bits = 7 }

    [[variants]]
    name = "tm14-ai"
    codec = "points"                    # points measured elsewhere, read from a file, not run
    csv = "../anchors/tm14_geometry_anchor.csv"
    where = { cond = "AI" }             # optional: keep the rows with this text in the column
    columns = { sequence = "seq" }      # optional: the file's column for a field; defaults:
    # sequence = "seq", rate = "rate", mbps = "mbps", d1 = "d1", d2 = "d2", bytes = "bytes",
    # enc = "enc_s_per_frame", dec = "dec_s_per_frame", peak = "peak", y = "y", cb = "cb",
    # cr = "cr", geom_bytes = "geom_bytes", tex_bytes = "tex_bytes"

``title`` (top level) and ``description`` (per variant) are free text for readers and
are otherwise ignored; any other unknown key is an error, so a typo cannot go unnoticed.
A sequence's ``fps`` (a capture subsampled in time, say) overrides the top-level one for
that sequence's runs and points: their Mbit/s, and the check of a points file's bytes.
``baselines`` names variants (other than the anchor) that the report also takes as the
reference, each in a BD-rate table of its own, beside the anchor's.
A run's options are the codec defaults, overridden by the variant's ``options``,
overridden by the rate point's. Every finished run is saved at once to
``OUT/runs/<sequence>__<variant>__<rate>.json`` (temporary file + rename) together
with a key hashed from everything that determines its result (codec and its build,
full options, frame files, peak, grid, the sequence's fps); a later call reuses a saved run whose key
matches, so an interrupted experiment resumes and a changed option reruns only what
it changes. ``OUT/results.json`` and ``OUT/results.csv`` collect all runs.

A ``points`` variant's CSV is read when the experiment is loaded (comma-separated, a
header line). Every kept row whose sequence column names a sequence of the experiment
becomes that sequence's record for the rate point its rate column names, with the
fields of a measured run the file has: ``mbps``, ``d1_psnr``, ``d2_psnr``, and
``bytes``, ``encode_s_per_frame``, ``decode_s_per_frame``, ``peak`` when the file has
those columns (the sequence, rate, mbps, d1 and d2 columns it must have, and any
column named in ``columns`` or ``where``); the texture's ``y_psnr``, ``cb_psnr``,
``cr_psnr`` from columns y, cb, cr, and ``geometry_mbps``, ``texture_mbps`` from the
bytes of columns geom_bytes and tex_bytes (as the file splits them: its ``bytes`` may
hold more, headers say, and must not hold less), as a measured textured run has them;
``frames`` and ``fps`` are the sequence's and ``source`` is the CSV's path relative to
the experiment file. A sequence without
rows has no points of that variant. The points are neither run nor cached; they are
checked instead, each failure a ConfigError naming the CSV and the line: numbers must
parse, each sequence and rate appear once, a ``peak`` column needs the sequence to
declare a peak within 1e-3 relative (PSNRs at different peaks do not compare), and
``bytes`` over the sequence's frames at the sequence's ``fps`` must give the file's
Mbit/s within 2 % (else the points were measured on other frames or at another frame
rate).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import re
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import tomllib

from .. import api, parallel, texture
from ..io import SequenceError, read_mesh, resolve_sequence
from ..mesh import Mesh
from .baselines import Draco, Encoded

__all__ = ["ConfigError", "RunError", "Experiment", "Run", "load_experiment", "plan_runs", "run_experiment",
           "measure", "load_results", "CODECS"]

#: Bump when a run record's fields or the way they are measured change: older saved runs
#: then no longer match and are measured again.
SCHEMA = 1


class ConfigError(ValueError):
    """An experiment file that cannot be used. The message names the file and the key."""


class RunError(ValueError):
    """A run that failed; the message names the run (sequence/variant/rate)."""


class Dynmesh:
    """The dynmesh codec (all-intra today), through :mod:`dynmesh.api`."""

    name = "dynmesh"
    DEFAULTS = {**api.DEFAULTS, **texture.TEXTURE_DEFAULTS}

    @staticmethod
    def version() -> str:
        return f"dynmesh {_package_version()} core {_core_digest()}"

    @staticmethod
    def encode(meshes: list[Mesh], **options) -> Encoded:
        result = api.encode_frames(meshes, **options)
        return Encoded(result.data, [int(f["bytes"]) for f in result.frames], len(result.data), result.texture_bytes)

    @staticmethod
    def decode(payload: bytes) -> list[Mesh]:
        return list(api.decode(payload))


#: Codec name in the experiment file -> adapter (see :mod:`dynmesh.baselines`).
CODECS = {"dynmesh": Dynmesh, "draco": Draco}


def _package_version() -> str:
    from .. import __version__

    return __version__


def _file_digest(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


# Short hash of the compiled core, so a rebuilt codec does not reuse old results. Taken
# when this module is imported, right after the core was loaded, so that a rebuild
# during a long experiment does not relabel results of the code actually running.
_CORE_DIGEST = _file_digest(api._core.__file__)


def _python_digest() -> str:
    """Short hash of the package's Python sources outside ``eval/``: the texture stage and
    the option defaults live there, so a change to them measures its runs again."""
    root = Path(api.__file__).parent
    h = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*.py") if "eval" not in p.relative_to(root).parts):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:16]


_PYTHON_DIGEST = _python_digest()


def _core_digest() -> str:
    return f"{_CORE_DIGEST} python {_PYTHON_DIGEST}"


# ---------------------------------------------------------------- the experiment file


@dataclass(frozen=True)
class Sequence:
    """A sequence as the experiment uses it: its frame files are resolved at load time."""

    name: str
    frames: tuple[Path, ...]
    peak: float | None
    fps: float  # its own, else the experiment's


@dataclass(frozen=True)
class RatePoint:
    name: str
    options: dict


@dataclass
class Variant:
    """A codec variant; a ``points`` variant has no options or rate points but its
    records (``points``), read from ``source`` (relative to the experiment file)."""

    name: str
    codec: str
    options: dict
    rates: list[RatePoint]
    source: str | None = None
    where: dict = field(default_factory=dict)
    points: list[dict] = field(default_factory=list)


@dataclass
class Experiment:
    """A parsed, checked experiment file."""

    path: Path
    anchor: str
    fps: float
    grid_size: int
    sequences: list[Sequence]
    variants: list[Variant]
    baselines: list[str] = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.path.stem

    def variant(self, name: str) -> Variant:
        return next(v for v in self.variants if v.name == name)


_TOP_KEYS = {"anchor", "baselines", "fps", "grid_size", "sequences", "variants", "rates", "title", "description"}
_SEQUENCE_KEYS = {"name", "path", "start", "count", "peak", "fps"}
_VARIANT_KEYS = {"name", "codec", "options", "rates", "description"}
_POINTS_KEYS = {"name", "codec", "csv", "where", "columns", "description"}
#: The codec of a variant whose records are read from a CSV file instead of measured.
POINTS = "points"
#: Record field (as ``columns`` names it) -> default CSV column.
_POINT_COLUMNS = {"sequence": "seq", "rate": "rate", "mbps": "mbps", "d1": "d1", "d2": "d2", "bytes": "bytes",
                  "enc": "enc_s_per_frame", "dec": "dec_s_per_frame", "peak": "peak",
                  "y": "y", "cb": "cb", "cr": "cr", "geom_bytes": "geom_bytes", "tex_bytes": "tex_bytes"}
#: Fields a CSV may lack (unless ``columns`` names their column): the record lacks them then.
_OPTIONAL_COLUMNS = {"bytes", "enc", "dec", "peak", "y", "cb", "cr", "geom_bytes", "tex_bytes"}
#: Integer fields of a points file.
_BYTE_COLUMNS = {"bytes", "geom_bytes", "tex_bytes"}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


def load_experiment(path: str | os.PathLike) -> Experiment:
    """Reads and checks an experiment file; every sequence's frames must exist.

    Raises ConfigError (a ValueError) with a one-line message naming the file and the
    offending key: unreadable or invalid TOML, a missing or unknown key, a wrong type,
    an unknown codec or option, a duplicate name, an anchor that is no variant, a
    sequence whose frames cannot be found, a points variant's CSV that cannot be read
    or fails a check (then naming the CSV and its line too).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"{path}: cannot read experiment file: {e.strerror or e}") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: invalid TOML: {e}") from None
    where = str(path)
    _no_unknown(doc, _TOP_KEYS, where)
    base = path.resolve().parent

    fps = float(_get(doc, "fps", (int, float), where, default=30))
    grid = _get(doc, "grid_size", int, where, default=1024)
    if not fps > 0 or grid < 2:
        raise ConfigError(f"{where}: fps must be positive and grid_size at least 2")
    sequences = [_sequence(s, base, fps, f"{where}: sequences[{i}]")
                 for i, s in enumerate(_list_of_tables(doc, "sequences", where))]
    _unique([s.name for s in sequences], f"{where}: sequences")
    rate_sets = _get(doc, "rates", dict, where, default={})
    variants = [_variant(v, rate_sets, sequences, base, f"{where}: variants[{i}]")
                for i, v in enumerate(_list_of_tables(doc, "variants", where))]
    _unique([v.name for v in variants], f"{where}: variants")

    names = [v.name for v in variants]
    anchor = _get(doc, "anchor", str, where, default=names[0])
    if anchor not in names:
        raise ConfigError(f"{where}: anchor {anchor!r} is not a variant (variants: {', '.join(names)})")
    baselines = _get(doc, "baselines", list, where, default=[])
    for b in baselines:
        if not isinstance(b, str) or b not in names:
            raise ConfigError(f"{where}: baselines: {b!r} is not a variant (variants: {', '.join(names)})")
        if b == anchor:
            raise ConfigError(f"{where}: baselines: {b!r} is the anchor, whose table the report has anyway")
    _unique(baselines, f"{where}: baselines")
    return Experiment(path, anchor, fps, grid, sequences, variants, baselines)


def _sequence(t: dict, base: Path, fps: float, where: str) -> Sequence:
    _no_unknown(t, _SEQUENCE_KEYS, where)
    name = _name(t, where)
    where = f"{where.rsplit(':', 1)[0]}: sequence {name!r}"
    spec = _get(t, "path", str, where)
    start = _get(t, "start", int, where, default=None)
    count = _get(t, "count", int, where, default=None)
    peak = _get(t, "peak", (int, float), where, default=None)
    if peak is not None and not peak > 0:
        raise ConfigError(f"{where}: peak must be positive, got {peak}")
    fps = _get(t, "fps", (int, float), where, default=fps)
    if not fps > 0:
        raise ConfigError(f"{where}: fps must be positive, got {fps}")
    # Relative to the experiment file, whatever the current directory is.
    full = spec if os.path.isabs(spec) else str(base / spec)
    try:
        frames = resolve_sequence(full, start, count)
    except SequenceError as e:
        raise ConfigError(f"{where}: path {spec!r}: {e}") from None
    return Sequence(name, tuple(Path(os.path.normpath(p)) for p in frames), None if peak is None else float(peak),
                    float(fps))


def _variant(t: dict, rate_sets: dict, sequences: list[Sequence], base: Path, where: str) -> Variant:
    name = _name(t, where)
    where = f"{where.rsplit(':', 1)[0]}: variant {name!r}"
    codec = _get(t, "codec", str, where)
    if codec not in CODECS and codec != POINTS:
        raise ConfigError(f"{where}: unknown codec {codec!r} (known: {', '.join([*CODECS, POINTS])})")
    _no_unknown(t, _POINTS_KEYS if codec == POINTS else _VARIANT_KEYS, where)
    if codec == POINTS:
        return _points_variant(t, name, sequences, base, where)
    options = _get(t, "options", dict, where, default={})
    rates = _get(t, "rates", (str, dict), where)
    if isinstance(rates, str):
        if rates not in rate_sets:
            raise ConfigError(f"{where}: rates = {rates!r} names no [rates.{rates}] table")
        rates = _get(rate_sets, rates, dict, f"{where.rsplit(':', 1)[0]}: rates")
    if not rates:
        raise ConfigError(f"{where}: no rate points")
    points = []
    for rate, opts in rates.items():
        if not isinstance(opts, dict):
            raise ConfigError(f"{where}: rate point {rate!r} must be a table of options")
        if not _NAME.match(rate):
            raise ConfigError(f"{where}: rate point name {rate!r} must be letters, digits, '_', '-', '.', '+'")
        merged = {**options, **opts}
        unknown = sorted(set(merged) - set(CODECS[codec].DEFAULTS))
        if unknown:
            raise ConfigError(f"{where}: rate point {rate!r}: unknown {codec} option(s) {', '.join(unknown)} "
                              f"(known: {', '.join(CODECS[codec].DEFAULTS)})")
        points.append(RatePoint(rate, merged))
    return Variant(name, codec, options, points)


def _points_variant(t: dict, name: str, sequences: list[Sequence], base: Path, where: str) -> Variant:
    """A points variant with the records of its CSV's kept rows (module docstring)."""
    spec = _get(t, "csv", str, where)
    keep = _text_table(t, "where", where)
    named = _text_table(t, "columns", where)
    _no_unknown(named, set(_POINT_COLUMNS), f"{where}: columns")
    path = Path(os.path.normpath(spec if os.path.isabs(spec) else base / spec))
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{where}: csv {spec!r}: cannot read {path}: {getattr(e, 'strerror', None) or e}") from None
    at = f"{where}: {path}"
    reader = csv.DictReader(io.StringIO(text))
    header = reader.fieldnames or []
    columns = {**_POINT_COLUMNS, **named}
    absent = [c for f, c in columns.items() if c not in header and (f not in _OPTIONAL_COLUMNS or f in named)]
    absent += [c for c in keep if c not in header]
    if absent:
        raise ConfigError(f"{at}: line 1: no column(s) {', '.join(absent)} (the header has {', '.join(header)})")
    columns = {f: c for f, c in columns.items() if c in header}
    by_name = {s.name: s for s in sequences}
    source = Path(os.path.relpath(path, base)).as_posix()
    points, lines = [], {}
    try:
        for row in reader:
            seq = by_name.get(row[columns["sequence"]])
            if seq is None or any(row[c] != v for c, v in keep.items()):
                continue
            point = _point(row, columns, seq, name, source, f"{at}: line {reader.line_num}")
            run = (seq.name, point["rate"])
            if run in lines:
                raise ConfigError(f"{at}: line {reader.line_num}: sequence {seq.name!r} rate {point['rate']!r} "
                                  f"already on line {lines[run]} (a 'where' filter keeps one condition)")
            lines[run] = reader.line_num
            points.append(point)
    except csv.Error as e:
        raise ConfigError(f"{at}: line {reader.line_num}: {e}") from None
    return Variant(name, POINTS, {}, [], source, keep, points)


def _point(row: dict, columns: dict, seq: Sequence, variant: str, source: str, at: str) -> dict:
    """The record of one CSV row (module docstring); ``at`` names the file and line."""
    rate = row[columns["rate"]] or ""
    if not _NAME.match(rate):
        raise ConfigError(f"{at}: rate {rate!r} must be letters, digits, '_', '-', '.', '+'")
    num = {f: _number(row[c], int if f in _BYTE_COLUMNS else float, f"{at}: column {c!r}")
           for f, c in columns.items() if f not in ("sequence", "rate")}
    if "peak" in num:
        _check_peak(num["peak"], seq, at)
    frames, fps = len(seq.frames), seq.fps
    if "bytes" in num and abs(_mbps(num["bytes"], frames, fps) - num["mbps"]) > 0.02 * num["mbps"]:
        raise ConfigError(f"{at}: {num['bytes']} bytes over the sequence's {frames} frames at {fps:g} fps are "
                          f"{_mbps(num['bytes'], frames, fps):.4f} Mbit/s, the file says {num['mbps']:g}: "
                          f"were the points measured on other frames?")
    parts = [f for f in ("geom_bytes", "tex_bytes") if f in num]
    if "bytes" in num and parts and sum(num[f] for f in parts) > num["bytes"]:
        split = " + ".join(f"{f} {num[f]}" for f in parts)
        raise ConfigError(f"{at}: {split} exceed the stream's {num['bytes']} bytes")
    return {
        "schema": SCHEMA, "sequence": seq.name, "variant": variant, "codec": POINTS, "source": source, "rate": rate,
        "frames": frames, "peak": num.get("peak", seq.peak), "fps": fps,
        **({"bytes": num["bytes"]} if "bytes" in num else {}),
        "bits_per_frame": num["mbps"] * 1e6 / fps, "mbps": num["mbps"], "d1_psnr": num["d1"], "d2_psnr": num["d2"],
        **{key: num[f] for f, key in zip(("y", "cb", "cr"), COLOUR_FIELDS) if f in num},
        **{key: _mbps(num[f], frames, fps)
           for f, key in (("geom_bytes", "geometry_mbps"), ("tex_bytes", "texture_mbps")) if f in num},
        **{key: num[f] for f, key in (("enc", TIMING_FIELDS[0]), ("dec", TIMING_FIELDS[1])) if f in num},
    }


def _number(text: str | None, kind: type, at: str) -> float | int:
    try:
        return kind(text)
    except (TypeError, ValueError):
        raise ConfigError(f"{at}: {text or ''!r} is not {'an integer' if kind is int else 'a number'}") from None


def _check_peak(peak: float, seq: Sequence, at: str) -> None:
    # A PSNR moves by 20 log10 of the peak ratio: points at another peak compare with nothing.
    if seq.peak is None:
        raise ConfigError(f"{at}: the file's points are at peak {peak}; sequence {seq.name!r} must declare "
                          f"its peak (peak = {peak})")
    if abs(peak - seq.peak) > 1e-3 * seq.peak:
        raise ConfigError(f"{at}: peak {peak} differs from sequence {seq.name!r}'s peak {seq.peak} "
                          f"(PSNRs at different peaks do not compare)")


def _text_table(t: dict, key: str, where: str) -> dict:
    table = _get(t, key, dict, where, default={})
    for k, v in table.items():
        if not isinstance(v, str):
            raise ConfigError(f"{where}: '{key}.{k}' must be str, got {type(v).__name__} {v!r}")
    return table


def _list_of_tables(doc: dict, key: str, where: str) -> list[dict]:
    value = _get(doc, key, list, where)
    if not value or not all(isinstance(v, dict) for v in value):
        raise ConfigError(f"{where}: '{key}' must be a non-empty array of tables ([[{key}]])")
    return value


def _get(t: dict, key: str, types, where: str, default=...):
    if key not in t:
        if default is ...:
            raise ConfigError(f"{where}: missing key '{key}'")
        return default
    value = t[key]
    # bool is an int in Python; no key here takes a bool where a number is meant.
    if not isinstance(value, types) or (isinstance(value, bool) and types in (int, (int, float))):
        names = "/".join(x.__name__ for x in (types if isinstance(types, tuple) else (types,)))
        raise ConfigError(f"{where}: '{key}' must be {names}, got {type(value).__name__} {value!r}")
    return value


def _name(t: dict, where: str) -> str:
    name = _get(t, "name", str, where)
    if not _NAME.match(name):
        raise ConfigError(f"{where}: name {name!r} must be letters, digits, '_', '-', '.', '+'")
    return name


def _no_unknown(t: dict, known: set, where: str) -> None:
    unknown = sorted(set(t) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")


def _unique(names: list[str], where: str) -> None:
    seen = set()
    for n in names:
        if n in seen:
            raise ConfigError(f"{where}: name {n!r} appears twice")
        seen.add(n)


# ---------------------------------------------------------------- runs


@dataclass(frozen=True)
class Run:
    """One sequence x variant x rate point, with everything a worker process needs."""

    sequence: Sequence
    variant: str
    codec: str
    rate: str
    options: dict = field(hash=False)
    fps: float
    grid_size: int
    base: Path  # directory of the experiment file: frame paths in records are relative to it

    @property
    def id(self) -> str:
        return f"{self.sequence.name}/{self.variant}/{self.rate}"

    @property
    def file_name(self) -> str:
        return f"{self.sequence.name}__{self.variant}__{self.rate}.json"

    def full_options(self) -> dict:
        return {**CODECS[self.codec].DEFAULTS, **self.options}

    def frame_names(self) -> list[str]:
        return [Path(os.path.relpath(p, self.base)).as_posix() for p in self.sequence.frames]

    def key(self) -> str:
        """Hash of everything that determines the run's result (not its timings)."""
        ident = {
            "schema": SCHEMA,
            "codec": self.codec,
            "codec_version": CODECS[self.codec].version(),
            "options": self.full_options(),
            "frames": [[n, p.stat().st_size] for n, p in zip(self.frame_names(), self.sequence.frames)],
            "peak": self.sequence.peak,
            "grid_size": self.grid_size,
            "fps": self.fps,
        }
        return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:24]


def plan_runs(exp: Experiment) -> list[Run]:
    """All runs in report order: sequence, then variant, then rate point. A points
    variant has none: its records come from its file (``Variant.points``)."""
    base = exp.path.resolve().parent
    return [Run(s, v.name, v.codec, r.name, r.options, s.fps, exp.grid_size, base)
            for s in exp.sequences for v in exp.variants for r in v.rates]


@lru_cache(maxsize=2)
def _read_frames(frames: tuple[Path, ...]) -> tuple[Mesh, ...]:
    # A worker usually measures several rate points of one sequence in a row.
    return tuple(read_mesh(p) for p in frames)


def measure(run: Run) -> dict:
    """Encodes, decodes and measures one run; returns its record (see module docstring).

    Times are wall-clock seconds per frame of the codec's encode and decode calls alone
    (reading files and measuring distortion are not counted). Raises RunError.
    """
    codec = CODECS[run.codec]
    try:
        refs = list(_read_frames(run.sequence.frames))
        t0 = time.perf_counter()
        enc = codec.encode(refs, **run.full_options())
        t1 = time.perf_counter()
        decoded = codec.decode(enc.payload)
        t2 = time.perf_counter()
        m = api.metrics(refs, decoded, peak=run.sequence.peak, grid_size=run.grid_size)
    except (ValueError, TypeError, OSError) as e:
        raise RunError(f"run {run.id}: {e}") from None
    n = len(refs)
    per_frame = [{"frame": i, "file": name, "bytes": b, **{k: f[k] for k in _FRAME_FIGURES if k in f}}
                 for i, (name, b, f) in enumerate(zip(run.frame_names(), enc.frame_bytes, m["frames"]))]
    colour = {k: m[k] for k in COLOUR_FIELDS if k in m}
    if colour:
        colour["texture_mbps"] = _mbps(enc.texture_bytes, n, run.fps)
        colour["geometry_mbps"] = _mbps(enc.total_bytes - enc.texture_bytes, n, run.fps)
    return {
        "schema": SCHEMA, "key": run.key(), "sequence": run.sequence.name, "variant": run.variant,
        "codec": run.codec, "codec_version": codec.version(), "rate": run.rate, "options": run.full_options(),
        "frames": n, "peak": m["peak"], "grid_size": run.grid_size, "fps": run.fps,
        "bytes": enc.total_bytes, "bits_per_frame": 8 * enc.total_bytes / n, "mbps": _mbps(enc.total_bytes, n, run.fps),
        "d1_psnr": m["d1_psnr"], "d2_psnr": m["d2_psnr"], **colour,
        "encode_s_per_frame": (t1 - t0) / n, "decode_s_per_frame": (t2 - t1) / n,
        "per_frame": per_frame,
    }


def _mbps(total_bytes: int, frames: int, fps: float) -> float:
    """Mbit/s of ``total_bytes`` spread over ``frames`` frames shown at ``fps``."""
    return 8 * total_bytes / frames * fps / 1e6


#: Texture PSNRs a run of a textured sequence adds to its record, beside the rates of
#: geometry and texture apart (``geometry_mbps``, ``texture_mbps``).
COLOUR_FIELDS = ("y_psnr", "cb_psnr", "cr_psnr")
_FRAME_FIGURES = ("d1_psnr", "d2_psnr", "d1_mse", "d2_mse") + COLOUR_FIELDS

#: Record fields that are measured times: they differ between otherwise identical runs.
TIMING_FIELDS = ("encode_s_per_frame", "decode_s_per_frame")


def _cached(out: Path, run: Run) -> dict | None:
    try:
        record = json.loads((out / "runs" / run.file_name).read_text())
    except (OSError, ValueError):
        return None  # absent or half-written by an older tool: measure again
    return record if record.get("key") == run.key() else None


def _save_json(path: Path, obj) -> None:
    api.write_bytes_atomic(path, (json.dumps(obj, indent=1, sort_keys=False) + "\n").encode())


def run_experiment(
    exp: Experiment,
    out: str | os.PathLike,
    *,
    jobs: int = 1,
    ray: str | None = None,
    force: bool = False,
    on_start: Callable[[Run], None] | None = None,
    on_done: Callable[[Run, dict, bool], None] | None = None,
) -> list[dict]:
    """Measures every run of ``exp`` not already saved in ``out`` (all of them with
    ``force``), ``jobs`` at a time in separate processes (or as tasks of the Ray cluster at
    ``ray``, one per CPU; see ``dynmesh.parallel.pool``), and returns all records in
    report order (sequence, variant, rate point), the points of points variants among
    them. ``on_start(run)`` is called when a run is handed to a worker;
    ``on_done(run, record, reused)`` when it is finished or found in the cache (points
    are no runs: neither is called for them). Each record is saved as soon as it
    exists, and results.json/csv are rewritten after every run. Raises RunError for a
    failed run, after saving the others that finished.
    """
    out = Path(out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    runs = plan_runs(exp)
    # Read from their files at load time: cheap, so never cached nor handed to a worker.
    points = [p for v in exp.variants for p in v.points]
    records: dict[str, dict] = {}
    todo = []
    for run in runs:
        record = None if force else _cached(out, run)
        if record is None:
            todo.append(run)
        else:
            records[run.id] = record
            if on_done:
                on_done(run, record, True)

    def so_far() -> list[dict]:
        return _in_report_order(exp, points + [records[r.id] for r in runs if r.id in records])

    def finish(run: Run, record: dict) -> None:
        _save_json(out / "runs" / run.file_name, record)
        records[run.id] = record
        write_summary(exp, so_far(), out)
        if on_done:
            on_done(run, record, False)

    if (jobs <= 1 and ray is None) or len(todo) <= 1:
        for run in todo:
            if on_start:
                on_start(run)
            finish(run, measure(run))
    else:
        pool, workers = parallel.pool(jobs, ray)
        with pool:
            pending, queue = {}, list(todo)
            try:
                while queue or pending:
                    # Keep exactly one run per worker in flight, so on_start means "started".
                    while queue and len(pending) < workers:
                        run = queue.pop(0)
                        if on_start:
                            on_start(run)
                        pending[pool.submit(measure, run)] = run
                    done, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in done:
                        run = pending.pop(fut)
                        finish(run, parallel.result_of(fut, f"run {run.id}"))
            except BaseException:
                for fut in pending:
                    fut.cancel()
                raise
    ordered = so_far()
    write_summary(exp, ordered, out)
    return ordered


def _in_report_order(exp: Experiment, records: list[dict]) -> list[dict]:
    """``records`` by sequence, then variant, as the experiment lists them; the sort is
    stable, so the rate points of a variant keep their order."""
    seq = {s.name: i for i, s in enumerate(exp.sequences)}
    var = {v.name: i for i, v in enumerate(exp.variants)}
    return sorted(records, key=lambda r: (seq[r["sequence"]], var[r["variant"]]))


# ---------------------------------------------------------------- results files

CSV_FIELDS = ["sequence", "variant", "codec", "rate", "options", "frames", "bytes", "bits_per_frame", "mbps",
              "d1_psnr", "d2_psnr", "encode_s_per_frame", "decode_s_per_frame", "peak", "key"]


def results_document(exp: Experiment, records: list[dict]) -> dict:
    """The content of results.json: the experiment as run and every run's record."""
    base = exp.path.resolve().parent
    return {
        "experiment": exp.name,
        "anchor": exp.anchor,
        "baselines": exp.baselines,
        "fps": exp.fps,
        "grid_size": exp.grid_size,
        "sequences": [{"name": s.name, "frames": len(s.frames), "peak": s.peak, "fps": s.fps,
                       "first": Path(os.path.relpath(s.frames[0], base)).as_posix()} for s in exp.sequences],
        "variants": [{"name": v.name, "codec": v.codec, "source": v.source, "where": v.where} if v.codec == POINTS
                     else {"name": v.name, "codec": v.codec, "options": v.options,
                           "rates": {r.name: r.options for r in v.rates}} for v in exp.variants],
        "runs": records,
    }


def write_summary(exp: Experiment, records: list[dict], out: Path) -> None:
    """Writes out/results.json and out/results.csv (each to a temporary name, then renamed)."""
    _save_json(out / "results.json", results_document(exp, records))
    buf = io.StringIO()
    extra = [k for k in COLOUR_FIELDS + ("geometry_mbps", "texture_mbps", "source") if any(k in r for r in records)]
    fields = CSV_FIELDS[:-4] + extra + CSV_FIELDS[-4:]
    w = csv.DictWriter(buf, fields, lineterminator="\n")
    w.writeheader()
    for r in records:
        # Points from a file have no options (nor key, bytes or times when the file lacks them).
        w.writerow({k: json.dumps(r[k], sort_keys=True) if k == "options" and k in r else _csv_value(r.get(k, ""))
                    for k in fields})
    api.write_bytes_atomic(out / "results.csv", buf.getvalue().encode())


def _csv_value(v):
    return repr(v) if isinstance(v, float) and math.isfinite(v) else v


def load_results(out: str | os.PathLike) -> dict:
    """Reads OUT/results.json as written by :func:`run_experiment`. Raises OSError/ValueError."""
    path = Path(out) / "results.json"
    try:
        return json.loads(path.read_text())
    except OSError as e:
        raise OSError(f"{path}: cannot read results ({e.strerror or e}); run the experiment first") from None
    except ValueError as e:
        raise ValueError(f"{path}: not a results file: {e}") from None
