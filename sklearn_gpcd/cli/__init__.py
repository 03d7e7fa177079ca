"""The ``gpcd`` command.

Subcommands: ``reproduce``, ``simulate`` and ``robots`` (the built-in
simulator), ``train``, ``diagnose``, ``calibrate``, ``teach`` and ``monitor`` (a
user's own recordings); ``gpcd COMMAND --help`` and the CLI page of the
documentation describe each.

Options naming a robot (``--robot``) take a built-in name or a URDF path;
without one, the robot comes from the recordings' metadata when they name it.
Recordings are read with :func:`sklearn_gpcd.io.load_recording` (``--column-map``:
a JSON object, a JSON file or a preset name); options that take several are
repeated (``--test a.csv --test b.csv``); output paths are checked first.

Exit status: 0 on success; 2 for bad input (a usage error, or a recording or
option the command cannot use), with ONE line ``gpcd COMMAND: error: MESSAGE``
on stderr naming the file and never a traceback; 130 on Ctrl-C (``gpcd COMMAND:
interrupted``); 143 on SIGTERM and 129 on SIGHUP (``gpcd COMMAND: stopped by
SIGTERM``), what systemd, docker and a closed terminal send: every verb stops the
way Ctrl-C stops it, its temporary files removed and the files it was writing left
as they were (``gpcd monitor`` writes its report first). Warnings print one line each, ``gpcd COMMAND: warning: MESSAGE``,
and the command goes on. Progress bars (with an ETA) go to stderr.

One module per verb (:mod:`~sklearn_gpcd.cli.train`, ``calibrate``,
``teach``, ``monitor``, ``diagnose``, ``reproduce`` with ``simulate`` and ``robots``),
each a thin layer over the library, and :mod:`~sklearn_gpcd.cli._args` for
what they share.
"""

import argparse
import sys
import warnings

from ..monitoring.stops import StopSignal, stop_signals
from . import calibrate, diagnose, monitor, reproduce, teach, train

__all__ = ["main", "build_parser", "parse_args"]


def build_parser():
    """The argument parser of the ``gpcd`` command.

    Returns
    -------
    parser : argparse.ArgumentParser

    Examples
    --------
    >>> from sklearn_gpcd.cli import build_parser
    >>> args = build_parser().parse_args(["reproduce", "--quick", "-o", "out"])
    >>> args.quick, args.output
    (True, 'out')
    >>> args = build_parser().parse_args(["diagnose", "--test", "held.csv", "train.csv"])
    >>> args.train, args.test
    (['train.csv'], ['held.csv'])
    """
    parser = argparse.ArgumentParser(
        prog="gpcd",
        description="Proprioceptive collision detection with Gaussian Processes.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    reproduce.add_parsers(sub)  # reproduce, simulate, robots
    train.add_parser(sub)
    diagnose.add_parser(sub)
    calibrate.add_parser(sub)
    teach.add_parser(sub)
    monitor.add_parser(sub)
    return parser


#: Subcommand -> its positional list of recordings (arguments left over after
#: the options, e.g. ``a.csv --test h.csv b.csv``, belong to it).
_RECORDING_POSITIONALS = {name: verb.RECORDINGS for name, verb in (
    ("train", train), ("diagnose", diagnose), ("calibrate", calibrate), ("monitor", monitor))}


def parse_args(argv=None):
    """Parse ``gpcd`` arguments; recordings may come before, between or after options.

    argparse takes one contiguous run of positionals, so ``gpcd diagnose a.csv
    --test h.csv b.csv`` would leave ``b.csv`` unrecognised; here such
    leftovers join the subcommand's list of recordings. Anything else left
    over is a usage error.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments without the program name; ``None`` reads ``sys.argv``.

    Returns
    -------
    args : argparse.Namespace

    Examples
    --------
    >>> args = parse_args(["diagnose", "a.csv", "--test", "h.csv", "b.csv"])
    >>> args.train, args.test
    (['a.csv', 'b.csv'], ['h.csv'])
    """
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    dest = _RECORDING_POSITIONALS.get(args.command)
    if extra and dest is not None and not any(a.startswith("-") for a in extra):
        getattr(args, dest).extend(extra)
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def main(argv=None):
    """Entry point of the ``gpcd`` command.

    Parameters
    ----------
    argv : list of str, default=None
        As for :func:`parse_args`.

    Returns
    -------
    status : int
        Process exit status (130 after Ctrl-C, 128 + the signal number after
        SIGTERM or SIGHUP).

    Examples
    --------
    >>> from sklearn_gpcd.cli import main
    >>> main(["robots"])  # doctest: +ELLIPSIS
    ur3 ...
    0
    """
    prefix = "gpcd"
    try:
        try:
            args = parse_args(argv)
        except SystemExit as exc:  # usage error or --help: argparse printed why
            return exc.code if isinstance(exc.code, int) else 2
        prefix = f"gpcd {args.command}"
        with warnings.catch_warnings(), stop_signals():  # SIGTERM, SIGHUP: like Ctrl-C
            warnings.showwarning = _warning_printer(prefix)
            try:
                return args.func(args)
            except (ValueError, OSError, ImportError) as exc:
                print(f"{prefix}: error: {_one_line(exc)}", file=sys.stderr)
                return 2
    except StopSignal as stop:  # the with blocks on the way cleaned up (temporary folders)
        print(f"{prefix}: {stop}", file=sys.stderr)
        return stop.exit_status
    except KeyboardInterrupt:
        fresh_line = "\n" if getattr(sys.stderr, "isatty", lambda: False)() else ""
        print(f"{fresh_line}{prefix}: interrupted", file=sys.stderr)  # after a bar's \r
        return 130


def _one_line(message):
    """``message`` (an exception or warning) on one line: whitespace runs become a space."""
    return " ".join(str(message).split())


def _warning_printer(prefix):
    """A :func:`warnings.showwarning` that prints ``PREFIX: warning: MESSAGE``."""

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prefix}: warning: {_one_line(message)}", file=sys.stderr if file is None
              else file)

    return show
