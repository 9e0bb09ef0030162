"""``fogsim`` — the one front door: ``render | fog | ila | depth | study | bench | levels | demo``.

Every subcommand's ``--help`` works without Blender, torch or Ultralytics: they are imported
only when a command needs them. Errors end a command with one line (never a traceback) and
the exit code of :func:`fogsim.errors.exit_code`: 0 done, 1 some items failed (each named),
2 usage or setup error, 130 interrupted.
"""
from __future__ import annotations

import argparse
import sys

from fogsim import __version__
from fogsim.errors import describe, exit_code


def build_parser() -> argparse.ArgumentParser:
    from fogsim.cli import bench, demo, depth, fog, ila, render, study

    parser = argparse.ArgumentParser(prog="fogsim", description="Labeled images in fog: render street scenes, "
                                     "fog rendered and real datasets, train and evaluate detectors per fog level.")
    parser.add_argument("--version", action="version", version=f"fogsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    render.add_parsers(sub)
    fog.add_parsers(sub)
    demo.add_parsers(sub)
    ila.add_parsers(sub)
    depth.add_parsers(sub)
    study.add_parsers(sub)
    bench.add_parsers(sub)
    return parser


def run_command(command, args, prog: str = "fogsim") -> int:
    """Run ``command(args)`` under the one error → exit-code policy."""
    try:
        return command(args)
    except (Exception, KeyboardInterrupt) as exc:
        from fogsim.errors import FogsimError

        if not isinstance(exc, (FogsimError, ValueError, OSError, KeyboardInterrupt)):
            raise  # a bug: the traceback is the useful report
        print(f"{prog}: error: {describe(exc)}", file=sys.stderr)
        return exit_code(exc)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(args.run, args)


if __name__ == "__main__":
    sys.exit(main())
