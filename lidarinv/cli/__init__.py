"""The ``lidarinv`` command line: one module per subcommand, chosen through a registry.

Each subcommand module defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. Modules are imported only when their command runs.

Exit status: 0 on success, 1 when some shots failed, 2 for a usage or input error (the
message names the file or option), 130 when interrupted (Ctrl-C), which prints one line
and leaves no partially written file (:mod:`lidarinv.cli.outputs`).
"""

import argparse
import importlib
import os
import signal
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


class Interrupted(Exception):
    """Raised by a command that has cleaned up after Ctrl-C; its message is the line
    printed (e.g. what a batch kept)."""


class _CtrlC:
    """Ctrl-C while a command runs: the first SIGINT silences stdout and stderr (so that
    what the interrupted code prints on its way out, such as emcee's report of the
    parameters it was evaluating and each traceback, never reaches the terminal) and
    raises KeyboardInterrupt; :func:`main` then prints one line. Numerical kernels may
    turn the KeyboardInterrupt into another exception (numba: ``SystemError``), so the
    flag, not the exception's type, says that the run was interrupted."""

    def __init__(self):
        self.seen, self._streams, self._previous = False, None, None

    def __enter__(self):
        self.seen, self._streams = False, None
        self._previous = signal.getsignal(signal.SIGINT)
        if self._previous is signal.default_int_handler:  # not where Ctrl-C is ignored
            signal.signal(signal.SIGINT, self._handle)
        return self

    def _handle(self, signum, frame):
        if not self.seen:
            self.seen = True
            self._streams = (sys.stdout, sys.stderr)
            sys.stdout = sys.stderr = open(os.devnull, "w")
        raise KeyboardInterrupt

    def restore(self) -> None:
        """Give the terminal back (after an interrupt): progress bars left open by the
        interrupted code stay as they were drawn instead of redrawing when collected."""
        if self._streams is not None:
            from tqdm import tqdm

            for bar in list(getattr(tqdm, "_instances", ())):
                bar.disable = True
            silenced = sys.stdout
            sys.stdout, sys.stderr = self._streams
            self._streams = None
            silenced.close()

    def __exit__(self, *exc):
        self.restore()
        if self._previous is signal.default_int_handler:
            signal.signal(signal.SIGINT, self._previous)


#: The Ctrl-C state of the running command.
CTRL_C = _CtrlC()


def interrupted(error: BaseException | None = None) -> bool:
    """Whether the running command was interrupted (Ctrl-C), whatever ``error`` the
    interruption became on its way out."""
    return CTRL_C.seen or isinstance(error, KeyboardInterrupt)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    prefix = f"lidarinv {args.command}"
    with CTRL_C:
        try:
            return int(args.handler(args) or 0)
        except Interrupted as stop:
            CTRL_C.restore()
            print(f"\n{prefix}: {stop}", file=sys.stderr)
            return 130
        except BaseException as error:
            if interrupted(error):
                CTRL_C.restore()
                print(f"\n{prefix}: interrupted; no partial output kept", file=sys.stderr)
                return 130
            if isinstance(error, ValueError | OSError):
                print(f"{prefix}: error: {error}", file=sys.stderr)
                return 2
            raise


if __name__ == "__main__":
    sys.exit(main())
