"""What an experiment's results say: BD-rate tables, RD plots and a Markdown page.

Everything here reads the results document of :mod:`dynmesh.eval.evaluate` (results.json)
and measures nothing itself, so a report can be rebuilt from saved results at any time.

BD-rate (DESIGN.md section 3): Bjontegaard delta rate of a variant against the anchor,
piecewise cubic Hermite (PCHIP) interpolation of log10(Mbit/s) as a function of PSNR,
averaged over the PSNR range both curves cover (the ``bjontegaard`` package,
``method="pchip"``, which matches the JCT-VC/JVET CTC spreadsheets). Negative means
fewer bits than the anchor for the same quality. The average row is the arithmetic
mean of the per-sequence BD-rates, as in the CTC spreadsheets. The rate is always the
total rate (every byte of the stream), also for the texture PSNRs: for a textured
sequence (one with runs that measured texture) the tables give D1, D2, Y, Cb and Cr
BD-rates, as the V-DMC test conditions compare them. The experiment's ``baselines``
are further references: the page has one BD-rate table against the anchor and one
against each of them (``bd_rows(results, reference)``).

Time ratios: test time / anchor time per frame, each side the geometric mean over its
rate points; the average row is the geometric mean over sequences (CTC spreadsheets
use geometric means for times as well).

Points taken from a file (records with a ``source``, of a ``points`` variant) take part
like measured runs, as anchor or as test; figures the file lacks show as n/a, and a
sequence the file has no points for is noted.
"""

from __future__ import annotations

import datetime
import math
import os
import platform
import re
import warnings
from pathlib import Path

import numpy as np

__all__ = ["bd_rate", "bd_rows", "rd_points", "plot_rd", "markdown", "write_report"]

METRICS = (("d1_psnr", "D1"), ("d2_psnr", "D2"))
#: Added for textured sequences: BD-rates on the total rate against each texture PSNR.
COLOUR_METRICS = (("y_psnr", "Y"), ("cb_psnr", "Cb"), ("cr_psnr", "Cr"))


def metrics_of(results: dict, sequence: str | None = None) -> tuple[tuple[str, str], ...]:
    """(record key, label) of every PSNR the report compares for ``sequence`` (for the
    experiment's tables without one): D1 and D2, and Y, Cb and Cr when it is textured."""
    return METRICS + (COLOUR_METRICS if _textured(results, sequence) else ())


def _textured(results: dict, sequence: str | None = None) -> bool:
    """Whether ``sequence`` (without one: any sequence) is textured: some run of it, measured
    or taken from a file, has texture PSNRs. A variant without them (a geometry codec) then
    shows n/a in the texture columns."""
    return any("y_psnr" in r for r in results["runs"] if sequence is None or r["sequence"] == sequence)


def _fps(results: dict, sequence: str) -> float:
    """The frame rate of ``sequence``'s Mbit/s: its own, else the experiment's (results
    written before sequences had one)."""
    own = next((s.get("fps") for s in results["sequences"] if s["name"] == sequence), None)
    return own or results["fps"]


def _labels(results: dict) -> list[str]:
    return [label.lower() for _, label in metrics_of(results)]


#: A metric's short name in the rows' keys (``d1``, ``cb``) -> its label (``D1``, ``Cb``).
_LABEL = {label.lower(): label for _, label in METRICS + COLOUR_METRICS}


def rd_points(results: dict, sequence: str, variant: str) -> list[dict]:
    """The run records of one sequence and variant, in the order of the rate points."""
    return [r for r in results["runs"] if r["sequence"] == sequence and r["variant"] == variant]


def bd_rate(anchor: list[tuple[float, float]], test: list[tuple[float, float]]) -> dict:
    """BD-rate in percent of ``test`` against ``anchor``, each a list of (rate, psnr).

    Returns {"bd_rate": percent or None, "overlap": fraction of the union PSNR range both
    curves cover, "note": why there is no value or why it is weak, or ""}. The points
    are sorted by PSNR first (PCHIP needs increasing abscissae); a curve whose rate does
    not grow with PSNR, or that has fewer than 2 points, gets no value.
    """
    a, t = _curve(anchor), _curve(test)
    for name, c in (("anchor", a), ("test", t)):
        if c is None:
            return {"bd_rate": None, "overlap": 0.0, "note": f"{name} curve has fewer than 2 distinct points"}
        if np.any(np.diff(c[0]) <= 0):
            return {"bd_rate": None, "overlap": 0.0, "note": f"{name} rate does not grow with PSNR"}
    lo, hi = max(a[1][0], t[1][0]), min(a[1][-1], t[1][-1])
    union = max(a[1][-1], t[1][-1]) - min(a[1][0], t[1][0])
    overlap = max(hi - lo, 0.0) / union if union > 0 else 0.0
    if overlap <= 0:
        return {"bd_rate": None, "overlap": 0.0, "note": "PSNR ranges do not overlap"}
    import bjontegaard

    with warnings.catch_warnings():
        # The package warns below 75 % overlap; the overlap is reported with the value instead.
        warnings.simplefilter("ignore")
        value = float(bjontegaard.bd_rate(a[0], a[1], t[0], t[1], method="pchip", require_matching_points=False,
                                          min_overlap=0))
    note = ""
    if min(len(a[0]), len(t[0])) < 4:
        note = "fewer than 4 rate points"
    elif overlap < 0.5:
        note = f"PSNR ranges overlap {overlap:.0%}"
    return {"bd_rate": value, "overlap": overlap, "note": note}


def _curve(points: list[tuple[float, float]]):
    """(rates, psnrs) sorted by PSNR, one point per PSNR value, or None if under 2 points."""
    best: dict[float, float] = {}
    for rate, psnr in points:
        if rate > 0 and math.isfinite(psnr):
            best[psnr] = min(rate, best.get(psnr, math.inf))
    if len(best) < 2:
        return None
    psnr = np.array(sorted(best))
    return np.array([best[p] for p in psnr]), psnr


def _geomean(values) -> float | None:
    values = [v for v in values if v is not None and v > 0]
    return float(np.exp(np.mean(np.log(values)))) if values else None


def bd_rows(results: dict, reference: str | None = None) -> list[dict]:
    """One row per sequence and variant other than ``reference`` (default: the anchor),
    then one "Average" row per variant.

    Row: sequence, variant, reference, d1_bd, d2_bd (percent or None), d1_note, d2_note,
    and for textured experiments y_bd, cb_bd, cr_bd and their notes (all at total rate),
    enc_ratio, dec_ratio (test time / reference time, or None: also when a side has no
    times). A side without points for the sequence gets the note "no points of NAME",
    one without a metric's PSNR "no Y PSNR of NAME"; a sequence without texture has no
    texture BD-rates ("no texture").
    """
    anchor = reference or results["anchor"]
    tests = [v["name"] for v in results["variants"] if v["name"] != anchor]
    rows = []
    for seq in (s["name"] for s in results["sequences"]):
        ref = rd_points(results, seq, anchor)
        textured = _textured(results, seq)
        for var in tests:
            pts = rd_points(results, seq, var)
            row = {"sequence": seq, "variant": var, "reference": anchor}
            # A file of points may skip a sequence: say so, not "fewer than 2 points".
            absent = " and ".join(v for v, p in ((anchor, ref), (var, pts)) if not p)
            for key, label in metrics_of(results):
                lacking = " and ".join(v for v, p in ((anchor, ref), (var, pts))
                                       if any(r.get(key) is None for r in p))
                if absent or (key in dict(COLOUR_METRICS) and not textured) or lacking:
                    bd = {"bd_rate": None}
                    note = (f"no points of {absent}" if absent else f"no {label} PSNR of {lacking}" if textured
                            else "no texture")
                else:
                    bd = bd_rate([(r["mbps"], r[key]) for r in ref], [(r["mbps"], r[key]) for r in pts])
                    note = bd["note"]
                row[f"{label.lower()}_bd"] = bd["bd_rate"]
                row[f"{label.lower()}_note"] = note
            for key, short in (("encode_s_per_frame", "enc"), ("decode_s_per_frame", "dec")):
                num, den = _geomean(r.get(key) for r in pts), _geomean(r.get(key) for r in ref)
                row[f"{short}_ratio"] = num / den if num and den else None
            rows.append(row)
    for var in tests:
        mine = [r for r in rows if r["variant"] == var]
        avg = {"sequence": "Average", "variant": var, "reference": anchor}
        for m in _labels(results):
            vals = [r[f"{m}_bd"] for r in mine]
            ok = [v for v in vals if v is not None]
            avg[f"{m}_bd"] = float(np.mean(ok)) if ok else None
            avg[f"{m}_note"] = "" if len(ok) == len(vals) else f"over {len(ok)} of {len(vals)} sequences"
        for t in ("enc", "dec"):
            avg[f"{t}_ratio"] = _geomean(r[f"{t}_ratio"] for r in mine)
        rows.append(avg)
    return rows


# ---------------------------------------------------------------- plots


def plot_rd(results: dict, sequence: str, metric: str, path: str | os.PathLike) -> Path:
    """One RD plot (total Mbit/s against PSNR, one line with markers per variant that has
    the metric) as PNG."""
    # Figure + Agg canvas rather than pyplot: no global backend state, safe in any process.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    label = dict(METRICS + COLOUR_METRICS)[metric]
    fig = Figure(figsize=(6.4, 4.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    markers = "osD^vP*X"
    for i, v in enumerate(results["variants"]):
        pts = sorted(rd_points(results, sequence, v["name"]), key=lambda r: r["mbps"])
        if not pts or any(r.get(metric) is None for r in pts):
            continue
        anchor = v["name"] == results["anchor"]
        ax.plot([r["mbps"] for r in pts], [r[metric] for r in pts], marker=markers[i % len(markers)],
                linewidth=2.2 if anchor else 1.5, label=v["name"] + (" (anchor)" if anchor else ""))
    ax.set_xlabel(f"total rate (Mbit/s at {_fps(results, sequence):g} fps)")
    ax.set_ylabel(f"{label} PSNR (dB)")
    ax.set_title(f"{sequence}: {label} PSNR")
    ax.grid(True, alpha=0.35)
    ax.set_xlim(left=0)
    ax.legend(loc="lower right")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # No timestamp in the file, so an unchanged result gives an unchanged image.
    fig.savefig(path, format="png", metadata={"Software": None})
    return path


# ---------------------------------------------------------------- the page


def _pct(v: float | None) -> str:
    return "n/a" if v is None else f"{v:+.1f} %"


def _ratio(v: float | None) -> str:
    if v is None:
        return "n/a"
    return f"{100 * v:.0f} %" if v >= 0.1 else f"{100 * v:.1f} %"


def _figure(r: dict, key: str, fmt: str, scale: float = 1.0) -> str:
    """``scale`` times a record's figure, formatted, or "n/a" when a file of points lacked it."""
    return "n/a" if r.get(key) is None else format(scale * r[key], fmt)


def _md_table(head: list[str], rows: list[list[str]], align: str | None = None) -> str:
    align = align or "l" + "r" * (len(head) - 1)
    rule = "|" + "|".join(":---" if a == "l" else "---:" for a in align) + "|"
    return "\n".join(["| " + " | ".join(head) + " |", rule] + ["| " + " | ".join(r) + " |" for r in rows])


def bd_markdown(results: dict, rows: list[dict], reference: str | None = None) -> str:
    """The BD-rate table against ``reference`` (default: the anchor; ``rows`` are
    ``bd_rows`` against it): per sequence, for each variant D1 and D2 (Y, Cb, Cr when
    textured) BD-rate and time ratios.

    In every row the best BD-rate of each metric is bold when it beats the reference, and the
    "best" columns name the variant with the fewest bits (the reference when nothing beats it,
    n/a when no variant has a value).
    """
    anchor = reference or results["anchor"]
    tests = [v["name"] for v in results["variants"] if v["name"] != anchor]
    labels = _labels(results)
    head = ["Sequence"]
    for v in tests:
        head += [f"{v} {_LABEL[m]}" for m in labels] + [f"{v} enc", f"{v} dec"]
    head += [f"best {_LABEL[m]}" for m in labels]
    body, notes = [], []
    for seq in [s["name"] for s in results["sequences"]] + ["Average"]:
        mine = {r["variant"]: r for r in rows if r["sequence"] == seq}
        cells = [f"**{seq}**" if seq == "Average" else seq]
        best = {}
        for m in labels:
            vals = {v: mine[v][f"{m}_bd"] for v in tests if mine[v][f"{m}_bd"] is not None}
            winner = min(vals, key=vals.get) if vals else None
            best[m] = None if not vals else winner if vals[winner] < 0 else anchor
        for v in tests:
            r = mine[v]
            for m in labels:
                text = _pct(r[f"{m}_bd"])
                if r[f"{m}_note"]:
                    notes.append(f"{seq}, {v}, {_LABEL[m]}: {r[f'{m}_note']}")
                    text += f" [{len(notes)}]"
                cells.append(f"**{text}**" if best[m] == v else text)
            cells += [_ratio(r["enc_ratio"]), _ratio(r["dec_ratio"])]
        cells += ["n/a" if best[m] is None else f"**{best[m]}**" for m in labels]
        body.append(cells)
    out = _md_table(head, body, "l" + "r" * (len(head) - 1 - len(labels)) + "l" * len(labels))
    out += "\n\n" + swapped_markdown(results, rows, anchor)
    if notes:
        out += "\n\n" + "  \n".join(f"[{i}] {n}" for i, n in enumerate(notes, 1))
    return out


def swapped_markdown(results: dict, rows: list[dict], reference: str | None = None) -> str:
    """The same comparison read the other way: the reference's (default: the anchor's)
    BD-rate against each variant.

    Swapping anchor and test negates the mean log-rate difference over the same PSNR
    interval, so the swapped BD-rate is exactly 1 / (1 + b) - 1 for each sequence; the
    average is again the arithmetic mean over sequences.
    """
    anchor = reference or results["anchor"]
    lines = []
    for v in [v["name"] for v in results["variants"] if v["name"] != anchor]:
        mine = [r for r in rows if r["variant"] == v and r["sequence"] != "Average"]
        parts = []
        for m in _labels(results):
            vals = [100 * (1 / (1 + r[f"{m}_bd"] / 100) - 1) for r in mine if r[f"{m}_bd"] is not None]
            parts.append(f"{_LABEL[m]} {_pct(float(np.mean(vals)) if vals else None)}")
        lines.append(f"Read the other way, {anchor} against {v}: {', '.join(parts)} (mean over sequences).")
    return "  \n".join(lines)


def rd_markdown(results: dict, sequence: str) -> str:
    """The points of one sequence: every variant and rate point (with texture PSNRs and
    the geometry and texture rates apart when the runs measured texture), then the
    variants that have none."""
    colour = [("geometry_mbps", "geometry Mbit/s", ".3f"), ("texture_mbps", "texture Mbit/s", ".3f"),
              ("y_psnr", "Y PSNR (dB)", ".2f"), ("cb_psnr", "Cb PSNR (dB)", ".2f"),
              ("cr_psnr", "Cr PSNR (dB)", ".2f")] if _textured(results, sequence) else []
    rows = []
    for v in results["variants"]:
        for r in rd_points(results, sequence, v["name"]):
            rows.append([v["name"], r["rate"], _figure(r, "bytes", ".0f", 1 / r["frames"]), f"{r['mbps']:.3f}",
                         f"{r['d1_psnr']:.2f}", f"{r['d2_psnr']:.2f}"]
                        + [_figure(r, k, f) for k, _, f in colour]
                        + [_figure(r, k, ".1f", 1000) for k in ("encode_s_per_frame", "decode_s_per_frame")])
    head = (["variant", "rate", "bytes/frame", "Mbit/s", "D1 PSNR (dB)", "D2 PSNR (dB)"] + [h for _, h, _ in colour]
            + ["enc ms/frame", "dec ms/frame"])
    table = _md_table(head, rows, "ll" + "r" * (len(head) - 2))
    absent = [v["name"] for v in results["variants"] if not rd_points(results, sequence, v["name"])]
    return table + (f"\n\nNo points for this sequence: {', '.join(absent)}." if absent else "")


def conditions_markdown(results: dict) -> str:
    """Sequences (frames, peak) and variants (codec, rate point options; for points, the
    rows kept and the file)."""
    seq = _md_table(["sequence", "frames", "fps", "first frame (relative to the experiment file)", "PSNR peak"],
                    [[s["name"], str(s["frames"]), f"{_fps(results, s['name']):g}", f"`{s['first']}`",
                      "box side" if s["peak"] is None else f"{s['peak']:g}"] for s in results["sequences"]], "lrrll")
    var_rows = []
    for v in results["variants"]:
        name = v["name"] + (" (anchor)" if v["name"] == results["anchor"] else "")
        if "source" in v:
            kept = ", ".join(f"{k}={x}" for k, x in v["where"].items())
            var_rows.append([name, v["codec"], f"rows with {kept}" if kept else "all rows",
                             f"read from `{v['source']}`"])
            continue
        common = ", ".join(f"{k}={_opt(x)}" for k, x in v["options"].items()) or "-"
        rates = "; ".join(f"{n}: " + ", ".join(f"{k}={_opt(x)}" for k, x in o.items() if v["options"].get(k) != x)
                          for n, o in v["rates"].items())
        var_rows.append([name, v["codec"], common, rates])
    var = _md_table(["variant", "codec", "options", "rate points"], var_rows, "llll")
    return seq + "\n\n" + var


def _opt(x) -> str:
    if isinstance(x, float) and x > 0 and x < 1 and abs(1 / x - round(1 / x)) < 1e-9:
        return f"1/{round(1 / x)}"  # base ratios read better as fractions
    return f"{x:g}" if isinstance(x, float) else str(x)


def markdown(results: dict, images: dict[tuple[str, str], str], command: str | None = None) -> str:
    """The whole page; ``images`` maps (sequence, metric) to a path relative to the page."""
    runs = [r for r in results["runs"] if "source" not in r]  # measured here, not taken from a file
    taken = len(results["runs"]) - len(runs)
    frames = sum(r["frames"] for r in runs)
    enc_s = sum(r["encode_s_per_frame"] * r["frames"] for r in runs)
    dec_s = sum(r["decode_s_per_frame"] * r["frames"] for r in runs)
    versions = sorted({f"{r['codec']}: {r['codec_version']}" for r in runs})
    parts = [
        f"# Rate-distortion results: {results['experiment']}",
        "",
        "Every figure on this page was measured by `dynmesh eval` "
        + (f"(`{command}`) " if command else "")
        + "and is recomputed from the saved results when the page is rebuilt"
        + (f", except {taken} points taken from files (codec `points`, see *Conditions*). " if taken else ". ")
        + f"{len(runs)} runs, {frames} coded frames; total codec time {enc_s:.1f} s encoding, {dec_s:.1f} s decoding.",
        "",
        f"Date: {datetime.date.today().isoformat()}  ",
        f"Machine: {_machine()}  ",
        "Codecs: " + "; ".join(versions),
        "",
        f"## BD-rate against {results['anchor']}",
        "",
        "Bjontegaard delta rate (PCHIP over log10 rate, on the PSNR range both curves cover; negative = fewer "
        "bits than the anchor for the same PSNR) for D1 and D2"
        + (" and, for textured sequences, Y, Cb and Cr, each against the total rate (geometry and texture)"
           if _textured(results) else "")
        + ", and encode (enc) / decode (dec) time of the "
        "variant as a percentage of the anchor's. Bold: the best BD-rate of the row when it beats the anchor; "
        "*best* names the variant needing the fewest bits.",
        "",
        bd_markdown(results, bd_rows(results)),
        "",
    ]
    for ref in results.get("baselines", []):
        parts += [f"## BD-rate against {ref}", "",
                  f"The same measures with {ref} as the reference (one of the experiment's baselines).", "",
                  bd_markdown(results, bd_rows(results, ref), ref), ""]
    parts += [
        "## How it was measured",
        "",
        "- **Distortion** (DESIGN.md section 3, the V-DMC common test conditions as in mmetric): both meshes are "
        f"sampled on one grid (grid size {results['grid_size']}) laid over the bounding box of the source frames of "
        "the run; D1 is point-to-point and D2 point-to-plane (the nearest point's own normal), symmetric (the larger "
        "MSE of the two directions); PSNR = 10 log10(3 p^2 / MSE).",
        "- **Peak p** (`src-max-bb-len`): the value the experiment file gives for the sequence (the shipped "
        "experiment uses the largest side of the whole source sequence's bounding box as `shared/data/README.md` "
        "lists it, rounded to 2 decimals there), else the largest side of the bounding box of the frames measured; "
        "per sequence in *Conditions* below.",
        "- **Sequence figure**: the mean over frames of the per-frame PSNR (not the PSNR of the mean MSE).",
        f"- **Rate**: every byte of the stream (dynmesh: header and all frame units; Draco: the sum of its "
        f"per-frame buffers), as Mbit/s at {_rates_fps(results)}"
        + (", texture included (geometry and texture rates apart in the tables); texture PSNR: colour sampled "
           "bilinearly at the same grid points and rounded to 8 bits as in mmetric, BT.709 YCbCr in [0, 1], peak 1, "
           "symmetric; Y, Cb and Cr BD-rates are on the "
           "total rate." if _textured(results) else ". Geometry only."),
        "- **Draco** codes each frame as an independent mesh (DracoPy, positions quantized over the frame's own box); "
        "it reorders and merges vertices, and the harness measures exactly what Draco decodes, like any decoder "
        "output.",
        "- **Times** are wall-clock seconds per frame of the encode and decode calls alone (no file reading, no "
        "metric), on the machine above, with as many runs in parallel as `--jobs` said and whatever else the machine "
        "was running; dynmesh uses several threads, Draco one. They are indicative and not part of any "
        "determinism check. Time ratios: geometric mean over rate points per sequence, geometric mean over "
        "sequences in the average row. BD-rate average: arithmetic mean over sequences.",
    ]
    if taken:
        parts.append("- **Points from files** (codec `points`, *Conditions* names the file): rate, D1/D2, times "
                     "and, where the file has them, Y/Cb/Cr and the geometry and texture rates, as the file gives "
                     "them, not measured here; the harness checks only the file's peak and bytes, where it has "
                     "them, against the sequence's peak, frames and frame rate. Their times were taken wherever the "
                     "points were measured, so time ratios against them are indicative only.")
    parts += [
        "",
        "## Conditions",
        "",
        conditions_markdown(results),
        "",
        "## Rate-distortion curves and points",
    ]
    for s in results["sequences"]:
        parts += ["", f"### {s['name']}", ""]
        pics = [f"![{s['name']} {label}]({images[(s['name'], key)]})" for key, label in metrics_of(results, s["name"])
                if (s["name"], key) in images]
        if pics:
            parts += [" ".join(pics), ""]
        parts.append(rd_markdown(results, s["name"]))
    return "\n".join(parts) + "\n"


def _rates_fps(results: dict) -> str:
    """The frame rate of the rates, with the sequences that have their own after it."""
    own = [f"{s['name']}: {_fps(results, s['name']):g}" for s in results["sequences"]
           if _fps(results, s["name"]) != results["fps"]]
    return f"{results['fps']:g} frames per second" + (f" ({', '.join(own)})" if own else "")


def _machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        cpu = re.search(r"model name\s*:\s*(.*)", Path("/proc/cpuinfo").read_text()).group(1)
    except (OSError, AttributeError):
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def write_report(results: dict, report_dir: str | os.PathLike, report_file: str = "results.md",
                 command: str | None = None) -> Path:
    """Writes the experiment's section of REPORT_DIR/REPORT_FILE and its plots in
    REPORT_DIR/<report file stem>/<experiment>/ (one PNG per sequence and metric, D1, D2, and
    Y, Cb, Cr for a textured sequence, each against the total rate; referenced
    relatively). Several experiments share a page: each owns the part between its markers,
    which a rerun replaces; the rest of the page is kept. Returns the page's path."""
    from ..api import write_bytes_atomic

    report_dir = Path(report_dir)
    page = report_dir / report_file
    img_dir = report_dir / Path(report_file).stem / results["experiment"]
    images = {}
    for s in results["sequences"]:
        for key, label in metrics_of(results, s["name"]):
            png = plot_rd(results, s["name"], key, img_dir / f"rd_{s['name']}_{label.lower()}.png")
            images[(s["name"], key)] = png.relative_to(report_dir).as_posix()
    section = _demoted(markdown(results, images, command))
    old = page.read_text() if page.exists() else ""
    write_bytes_atomic(page, _with_section(old, results["experiment"], section).encode())
    return page


PAGE_TITLE = "# Results\n\nEach section below is written by `dynmesh eval` for one experiment; rerunning an experiment replaces its own section.\n"


def _demoted(text: str) -> str:
    """Every Markdown heading one level deeper, so that sections nest under the page title."""
    return "\n".join("#" + line if line.startswith("#") else line for line in text.splitlines())


def _with_section(page: str, name: str, section: str) -> str:
    """``page`` with the section between ``name``'s markers replaced (or appended)."""
    start, end = f"<!-- dynmesh-eval:{name}:start -->", f"<!-- dynmesh-eval:{name}:end -->"
    block = f"{start}\n{section.rstrip()}\n{end}"
    if start in page and end in page:
        return page[: page.index(start)] + block + page[page.index(end) + len(end):]
    if "<!-- dynmesh-eval:" not in page:
        page = PAGE_TITLE
    return page.rstrip() + "\n\n" + block + "\n"
