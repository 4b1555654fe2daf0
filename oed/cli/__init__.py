"""The ``oed`` command line.

Each verb lives in its own module of this package and exposes two functions::

    register(subparsers) -> argparse.ArgumentParser   # adds the verb and its options
    run(args: argparse.Namespace) -> int               # does the work, returns the exit code

Verb modules do not import one another. What several verbs share lives in :mod:`oed.cli.shared.common` (robot, data,
derivative and streaming options, shared checks and messages), :mod:`oed.cli.shared.asbuilt` (the robot as built) and
:mod:`oed.cli.shared.paths`; reading and preparing the records is one library call
(:func:`estimation.identification.prepared.prepare_records`).

Errors a user can cause (bad input files, impossible bounds, unknown robots) are raised as
``ValueError``/``TypeError``/``OSError`` subclasses by the library; :func:`main` turns them into
a one-line message on stderr and exit code 2, never a traceback. Anything else is a bug: it
too is one line on stderr (exit code 1; ``OED_TRACEBACK=1`` prints the traceback).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback
from collections.abc import Sequence
from importlib import metadata

import oed
from dynamics.runtime.threads import single_threaded_blas
from oed.cli.shared.paths import check_paths

# verb module names, in the order ``oed --help`` lists them
VERB_MODULES: tuple[str, ...] = ("model", "design", "simulate", "identify", "aprbs", "servo_simulate", "servo_fit", "diagnose",
                                 "predict", "export", "demo")

EXIT_USER_ERROR = 2
EXIT_INTERNAL_ERROR = 1
#: Ctrl-C (128 + SIGINT, as shells report it)
EXIT_INTERRUPTED = 130
#: set to show the traceback of an internal error
TRACEBACK_VARIABLE = "OED_TRACEBACK"


#: the distribution whose version ``oed --version`` prints
DISTRIBUTION = "robot-oed"


def package_version() -> str:
    """The installed distribution's version, else :data:`oed.__version__` (the source tree run uninstalled);
    both come from ``oed.__version__`` (pyproject.toml reads it at install time)."""
    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return oed.__version__


def verbs_to_register(argv: Sequence[str]) -> tuple[str, ...]:
    """The verb module of the verb the command line starts with (``servo-fit`` -> ``servo_fit``), alone: a run
    imports its own verb's libraries only (``oed design`` neither pandas nor scipy.signal). Every verb for
    anything else (``--help``, ``--version``, no verb, a misspelt one), so that argparse lists them all."""
    if argv:
        module = argv[0].replace("-", "_")
        if module in VERB_MODULES and argv[0] == module.replace("_", "-"):
            return (module,)
    return VERB_MODULES


def build_parser(verbs: Sequence[str] = VERB_MODULES) -> argparse.ArgumentParser:
    """Return the top-level parser with ``verbs`` (default: every verb) registered."""
    parser = argparse.ArgumentParser(
        prog="oed",
        description="Optimal experiment design and dynamic-parameter identification of robot manipulators.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    subparsers = parser.add_subparsers(dest="verb", metavar="VERB")
    subparsers.required = True
    for name in verbs:
        module = importlib.import_module(f"oed.cli.{name}")
        verb_parser = module.register(subparsers)
        verb_parser.set_defaults(run=module.run, derived_outputs=getattr(module, "derived_outputs", None))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``oed`` console script."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(verbs_to_register(argv))  # imports the verb (numpy, CasADi…): the first second of a run
    except KeyboardInterrupt:
        print("oed: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    args = parser.parse_args(argv)
    try:
        check_paths(args, args.derived_outputs)  # before any work: no output over an input or another output
        with single_threaded_blas():  # threaded BLAS on tall, thin matrices only loses (dynamics.runtime.threads)
            return int(args.run(args))
    except (ValueError, TypeError, OSError, KeyError, RuntimeError) as error:
        message = str(error) or error.__class__.__name__
        print(f"oed {args.verb}: error: {message}", file=sys.stderr)
        return EXIT_USER_ERROR
    except (MemoryError, OverflowError, FloatingPointError) as error:  # sizes or values asked for are too large
        print(f"oed {args.verb}: error: the request is too large for this machine or for floating point "
              f"({error.__class__.__name__}: {error or 'no detail'}): reduce the sizes or values given", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print(f"oed {args.verb}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # a bug rather than bad input: still one readable line, not a bare traceback
        print(f"oed {args.verb}: internal error: {error.__class__.__name__}: {error} "
              f"(a bug; set {TRACEBACK_VARIABLE}=1 to see the traceback)", file=sys.stderr)
        if os.environ.get(TRACEBACK_VARIABLE):
            traceback.print_exc()
        return EXIT_INTERNAL_ERROR
