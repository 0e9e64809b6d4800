"""Command line: list and run the demos of the paper's examples.

::

    python3 -m dwr_signorini list
    python3 -m dwr_signorini run bar_2d --levels 6 --output results/bar
    mpirun -n 2 python3 -m dwr_signorini run obstacle_3d

``run`` executes ``demos/<DEMO>.py`` of the source checkout (the ``demos`` folder next to the
package) with :mod:`runpy`, as ``__main__`` and with the remaining arguments as its
``sys.argv``, so ``python3 -m dwr_signorini run DEMO ARGS`` is the same as
``python3 demos/DEMO.py ARGS``. The ``dwr-signorini`` console script calls :func:`main`.
"""

from __future__ import annotations

import argparse
import os
import runpy
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

__all__ = ["demo_description", "demos_dir", "find_demos", "main"]


def demos_dir() -> Path:
    """The ``demos`` folder of the checkout this package lives in.

    ``DWR_SIGNORINI_DEMOS`` overrides it (e.g. for an installed package and a separate copy of
    the demos).
    """
    env = os.environ.get("DWR_SIGNORINI_DEMOS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent.parent / "demos"


def find_demos() -> dict[str, Path]:
    """Demo name -> script, for every ``demos/*.py`` (sorted by name)."""
    folder = demos_dir()
    if not folder.is_dir():
        return {}
    return {p.stem: p for p in sorted(folder.glob("*.py")) if not p.name.startswith("_")}


def demo_description(path: Path) -> str:
    """The demo's one-line description: the title of its Markdown header (``# # Title``)."""
    try:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("# # "):
                    return line[4:].strip()
    except OSError:
        pass
    return ""


def _print_list(demos: dict[str, Path], file: TextIO | None = None) -> None:
    width = max((len(n) for n in demos), default=0)
    for name, path in demos.items():
        print(f"  {name:<{width}}  {demo_description(path)}", file=file)


def _rank() -> int:
    """MPI rank if mpi4py is already initialised by the launcher, else 0 (no MPI start-up)."""
    for key in ("OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"):
        if key in os.environ:
            return int(os.environ[key])
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python3 -m dwr_signorini`` and the ``dwr-signorini`` script.

    Args:
        argv: Arguments without the program name (default: ``sys.argv[1:]``).

    Returns:
        The exit status (0 on success, 2 for usage errors such as an unknown demo).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(
        prog="python3 -m dwr_signorini",
        description="Goal-oriented adaptive FEM for Signorini's problem: the paper's demos.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the demos with a one-line description")
    run = sub.add_parser(
        "run",
        help="run a demo: run DEMO [demo options...] (see run DEMO --help)",
        add_help=False,
    )
    run.add_argument("demo", help="demo name, e.g. bar_2d (see `list`)")
    run.add_argument("demo_args", nargs=argparse.REMAINDER, help="options passed to the demo")

    if argv and argv[0] == "run" and len(argv) >= 2 and argv[1] in ("-h", "--help"):
        run.print_help()
        return 0
    args = parser.parse_args(argv)
    demos = find_demos()
    if args.command == "list":
        if not demos:
            print(
                f"no demos found in {demos_dir()} (they are part of the source checkout)",
                file=sys.stderr,
            )
            return 2
        if _rank() == 0:
            print("demos (python3 -m dwr_signorini run DEMO [options], DEMO --help for options):")
            _print_list(demos)
        return 0

    name = args.demo[:-3] if args.demo.endswith(".py") else args.demo
    if name not in demos:
        if _rank() == 0:
            where = demos_dir()
            msg = f"unknown demo {args.demo!r}" if demos else f"no demos found in {where}"
            print(f"python3 -m dwr_signorini: {msg}; available demos:", file=sys.stderr)
            _print_list(demos, file=sys.stderr)
        return 2
    path = demos[name]
    saved = sys.argv
    sys.argv = [str(path), *args.demo_args]
    try:
        runpy.run_path(str(path), run_name="__main__")
    except SystemExit as exc:  # argparse in the demo (--help, usage errors)
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    finally:
        sys.argv = saved
    return 0


if __name__ == "__main__":
    sys.exit(main())
