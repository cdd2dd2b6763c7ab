"""The ``dofview`` command line: a thin layer that finds each command's parser in its package
(``render`` in :mod:`dofview.cli.render`, ``view``, ``bench`` and ``train`` beside their code).

User mistakes (bad files, bad values) print one line ``dofview: error: …`` and exit 2, with no
traceback; outputs are written whole or not at all.
"""

from __future__ import annotations

import argparse
import re
import sys
import warnings
from typing import Sequence

from dofview import __version__
from dofview.errors import DofviewError, DofviewWarning

# ---- entry point -----------------------------------------------------------------------------------
COMMAND_MODULES = ("dofview.cli.render", "dofview.viewer.app", "dofview.bench.cli", "dofview.train.cli")


class _Parser(argparse.ArgumentParser):
    """argparse with dofview's one-line errors (sub-commands inherit it): exit status 2, no usage dump."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        # a value that starts like a negative number (--blur -2%, --focus -1:3) is a value, so that its own
        # parser names what is wrong with it; no dofview option starts with a digit (Python 3.13's rule)
        self._negative_number_matcher = re.compile(r"-\.?\d")

    def error(self, message: str):
        missing = re.fullmatch(r"argument (?:\S+/)?(--\S+): expected one argument", message)
        if missing:  # `--up -z`: argparse took the value for an option
            message += f" (one that starts with '-' is written {missing.group(1)}=-…)"
        self.exit(2, f"dofview: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="dofview", description="A camera lens for trained 3D Gaussian Splatting scenes.")
    parser.add_argument("--version", action="version", version=f"dofview {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    import importlib

    for name in COMMAND_MODULES:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name and (e.name == name or name.startswith(e.name + ".")):
                continue  # that command is not part of this build
            raise
        mod.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings():
        python_show = warnings.showwarning

        def show(message, category, *rest, **kw) -> None:  # repaired input: one line, no source excerpt
            if issubclass(category, DofviewWarning):
                print(f"dofview: warning: {message}", file=sys.stderr)
            else:
                python_show(message, category, *rest, **kw)

        warnings.simplefilter("always", DofviewWarning)
        warnings.showwarning = show
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.run(args) or 0)
    except DofviewError as e:
        print(f"dofview: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dofview: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
