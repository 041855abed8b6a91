"""The command line's arguments: how a mistake in them is reported, and the exit statuses.

Every error, argparse's included, is one line on stderr and exit status 1 (README.md,
"Exit status", and every command's ``--help`` say the same as ``EXIT_STATUS_HELP``).
Paths given where one sequence was expected are what a shell makes of an unquoted
pattern (``dynmesh encode frames/*.obj``): the message says to quote it or give the folder.

Standard library only: every command imports this.
"""

from __future__ import annotations

import argparse
import os

#: Exit statuses, as README.md ("Exit status") and every command's --help state them.
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130
#: 128 + SIGPIPE: what a shell reports for a command whose reader went away (`yes | head`).
EXIT_PIPE_CLOSED = 141
EXIT_STATUS_HELP = ("Exit status: 0 when the command did its work; 1 for any error (a bad option or argument, an "
                    "unreadable or malformed input, an output refused before any work, damaged frames); 130 when "
                    "interrupted; 141 when the reader of the standard output went away (as `| head` does), "
                    "which ends the command quietly.")


class Parser(argparse.ArgumentParser):
    """argparse with the command line's own error report: one line that says where to look,
    and status 1 (``EXIT_ERROR``) as for every other error, not argparse's 2."""

    def error(self, message: str):
        self.exit(EXIT_ERROR, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def parse(top: argparse.ArgumentParser, argv: list[str] | None) -> argparse.Namespace:
    """The command line, or an error naming what is wrong; extra paths where a sequence was
    expected are what the shell makes of an unquoted pattern, and the message says so."""
    args, extra = top.parse_known_args(argv)
    if extra:
        command = top._subparsers._group_actions[0].choices[args.command]
        if args.command in SEQUENCE_INPUTS and not any(e.startswith("-") for e in extra):
            command.error(expanded_pattern(args, extra))
        command.error(f"unrecognized arguments: {' '.join(extra)}")
    return args


#: The commands whose inputs are sequences (a folder, a pattern): the positionals that name them.
SEQUENCE_INPUTS = {"encode": ("input",), "metrics": ("reference", "decoded")}


def expanded_pattern(args: argparse.Namespace, extra: list[str]) -> str:
    """The message for ``dynmesh encode frames/*.obj -o s.dmsh`` (unquoted): the pattern the
    files suggest, quoted, and their folder."""
    given = [getattr(args, name) for name in SEQUENCE_INPUTS[args.command]] + extra
    files = [p for p in given if not os.path.isdir(p)] or given
    folder = os.path.dirname(files[0]) or "."
    suffixes = {os.path.splitext(p)[1] for p in files if (os.path.dirname(p) or ".") == folder}
    pattern = os.path.join(folder, "*" + (suffixes.pop() if len(suffixes) == 1 else ""))
    expected = "one input was" if len(SEQUENCE_INPUTS[args.command]) == 1 else "two (reference and decoded) were"
    return (f"{len(given)} paths were given where {expected} expected: the shell expanded an unquoted "
            f"pattern into its files. Quote the pattern ('{pattern}') or give the folder ({folder}/)")


def non_negative(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = -1
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return v


def jobs(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of processes or auto, got {text!r}") from None


#: The largest ``metrics --grid-size``: ``api.MAX_GRID_SIZE``, which the tests compare with
#: this (the API imports numpy, which parsing a command line must not).
MAX_GRID_SIZE = 16384


def grid_size(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        v = None
    if v is None or not 2 <= v <= MAX_GRID_SIZE:
        raise argparse.ArgumentTypeError(f"grid size must be a whole number from 2 to {MAX_GRID_SIZE}, not {text!r}")
    return v


def sequence_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--start", type=int, help="first frame (index into the sorted list, or number for a printf pattern)")
    p.add_argument("--count", type=int, help="number of frames")


def parallel_args(p: argparse.ArgumentParser, what: str, default: int | str = 1) -> None:
    g = p.add_mutually_exclusive_group()
    auto = " ('auto': one per core, at most one per group)" if default == "auto" else ""
    g.add_argument("--jobs", type=jobs if default == "auto" else int, default=default,
                   help=f"{what} in parallel, in separate local processes{auto} (default {default})")
    g.add_argument("--ray", metavar="ADDRESS",
                   help=f"{what} as tasks of the Ray cluster at ADDRESS ('auto': the one this machine is part of), one "
                        'per CPU; needs pip install "dynmesh[ray]"')


def common_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress on stderr (on a terminal a bar naming the latest frame, with the time left; "
                        "otherwise one line per frame)")
