"""The ``lidarinv`` command line: one module per subcommand, chosen through a registry.

Each subcommand module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. Modules are imported only when their command runs.

Exit status: 0 on success, 1 when some shots failed, 2 for a usage or input error (the
message names the file or option), 130 when interrupted (Ctrl-C), which prints one line
and leaves no partially written file (:mod:`lidarinv.cli.outputs`).
"""

import argparse
import importlib
import sys

#: Subcommand name → module implementing it.
COMMANDS = {
    "simulate": "lidarinv.cli.simulate",
    "metrics": "lidarinv.cli.metrics",
    "invert": "lidarinv.cli.invert",
    "batch": "lidarinv.cli.batch",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lidarinv", description="Lidar waveform simulation and Bayesian inversion"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name != module_name:
                raise
            continue  # a command whose module is not built yet
        command = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(command)
        command.set_defaults(handler=module.run)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except (ValueError, OSError) as error:
        print(f"lidarinv {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\nlidarinv {args.command}: interrupted; no partial output kept", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
