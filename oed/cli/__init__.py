"""The ``oed`` command line.

Each verb lives in its own module of this package and exposes two functions::

    register(subparsers) -> argparse.ArgumentParser   # adds the verb and its options
    run(args: argparse.Namespace) -> int               # does the work, returns the exit code

Verb modules do not import one another. The table of verbs (:mod:`oed.cli.shared.verbs`: name, module, summary) is
what the top-level parser lists; a run imports the module of its own verb alone (each verb's imports are most of a
short run's first second). What several verbs share lives in :mod:`oed.cli.shared.common` (robot, data,
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
from collections.abc import Collection, Sequence
from importlib import metadata

import oed
from dynamics.runtime.allocator import keep_freed_memory
from dynamics.runtime.threads import single_threaded_blas
from oed.cli.shared.paths import check_paths
from oed.cli.shared.verbs import VERBS

# verb module names, in the order ``oed --help`` lists them
VERB_MODULES: tuple[str, ...] = tuple(verb.module for verb in VERBS)

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


def build_parser(verbs: Collection[str] | None = None) -> argparse.ArgumentParser:
    """Return the top-level parser with the verbs named in ``verbs`` registered (their modules imported; default:
    every verb), the others listed by their summary alone."""
    parser = argparse.ArgumentParser(
        prog="oed",
        description="Optimal experiment design and dynamic-parameter identification of robot manipulators.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    subparsers = parser.add_subparsers(dest="verb", metavar="VERB")
    subparsers.required = True
    for verb in VERBS:
        if verbs is not None and verb.name not in verbs:
            subparsers.add_parser(verb.name, help=verb.summary)  # listed; never run (main registers the verb run)
            continue
        module = importlib.import_module(f"oed.cli.{verb.module}")
        verb_parser = module.register(subparsers)
        verb_parser.set_defaults(run=module.run, derived_outputs=getattr(module, "derived_outputs", None))
    return parser


def requested_verb(argv: Sequence[str]) -> str | None:
    """The verb of a command line: its first word that is not an option (the top-level options take no value)."""
    return next((word for word in argv if not word.startswith("-")), None)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``oed`` console script."""
    argv = sys.argv[1:] if argv is None else list(argv)
    verb = requested_verb(argv)
    try:
        parser = build_parser(() if verb is None else (verb,))  # imports that verb's module alone
    except KeyboardInterrupt:
        print("oed: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    args = parser.parse_args(argv)
    if hasattr(args, "topic"):  # --data, --validate, --test as log sources that carry --topic and --columns
        importlib.import_module("oed.cli.shared.common").bind_log_options(args)
    keep_freed_memory()  # a run's arrays come and go by the thousand: their pages kept, not faulted in again
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
