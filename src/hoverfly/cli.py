"""The `hoverfly` command: argument parsing and dispatch to the sub-command modules.

Each area registers its sub-commands from its own module (`cli_*.py`), so this file
stays a table. User mistakes (`UserError`) print one line and exit 2.
"""

import argparse
import importlib
import sys

from hoverfly import __version__
from hoverfly.errors import UserError

# Modules that add sub-commands: each has register(subparsers).
COMMAND_MODULES = (
    "hoverfly.cli_fly",
    "hoverfly.cli_rx",
    "hoverfly.cli_esc",
    "hoverfly.cli_sim",
    "hoverfly.cli_params",
    "hoverfly.cli_connect",
    "hoverfly.cli_maint",
    "hoverfly.cli_log",
    "hoverfly.cli_flash",
    "hoverfly.cli_sweep",
    "hoverfly.cli_tune",
    "hoverfly.cli_gcs",
)


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UserError(message)


def build_parser():
    parser = _Parser(prog="hoverfly", description="A flight controller in Python, with a built-in simulator.")
    parser.add_argument("--version", action="version", version="hoverfly " + __version__)
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    try:
        parser = build_parser()
        if not argv:
            argv = ["fly"]  # no arguments: fly the demo
        args = parser.parse_args(argv)
        if getattr(args, "func", None) is None:
            parser.print_help()
            return 2
        return args.func(args) or 0
    except UserError as exc:
        print("hoverfly: error: %s" % exc, file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
