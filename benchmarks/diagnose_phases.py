"""Where the time of one ``oed diagnose`` run goes: wall and CPU seconds of each phase, in process.

Run it as the command itself, from the repository root::

    PYTHONPATH=. python benchmarks/diagnose_phases.py diagnose --urdf kuka_lwr4.urdf --data train.csv \\
        --validate validate.csv --test test.csv --out report.json

The options are parsed by the command line's parser and handed to the library call
(:func:`oed.workflows.diagnose.diagnose`, what ``oed diagnose`` runs). The phases (imports of the parser and the
library, the derivatives chosen by held-out error, the records prepared with them, the candidate search, the
rest of the diagnosis, the test record's errors, the outputs) are timed by wrapping the library functions that
make them; each is printed with its share of the total, so that runs on
machines of other speeds compare (``benchmarks/README.md``, "Where the time of `oed diagnose` goes").
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable

START = (time.perf_counter(), time.process_time())

import estimation.diagnosis.forward_selection as forward  # noqa: E402
import estimation.identification.prepared as prepared  # noqa: E402
import oed.cli as cli  # noqa: E402
import oed.workflows.diagnose as verb  # noqa: E402

PARSER = cli.build_parser(("diagnose",))
IMPORTED = (time.perf_counter() - START[0], time.process_time() - START[1])
SPENT: dict[str, list[float]] = {}


def timed(owner: object, name: str, label: str) -> None:
    """Replace ``owner.name`` by a wrapper adding its wall and CPU seconds to ``SPENT[label]``."""
    original: Callable = getattr(owner, name)

    def wrapper(*args, **kwargs):
        wall, cpu = time.perf_counter(), time.process_time()
        try:
            return original(*args, **kwargs)
        finally:
            total = SPENT.setdefault(label, [0.0, 0.0])
            total[0] += time.perf_counter() - wall
            total[1] += time.process_time() - cpu

    setattr(owner, name, wrapper)


def main(argv: list[str]) -> int:
    timed(prepared, "choose_plan", "  derivatives chosen by held-out error")
    timed(verb, "prepare_records", "reading and preparation")
    timed(forward.DiagnosisSearch, "run", "  the candidate search (rounds)")
    timed(verb, "diagnose_model", "diagnosis (search, statistics, tracing)")
    timed(verb, "test_errors", "test record's errors")
    timed(verb.DiagnoseRun, "write", "outputs (report.json, --report)")
    args = PARSER.parse_args(argv)
    options = {name: value for name, value in vars(args).items()
               if name in {field.name for field in dataclasses.fields(verb.DiagnoseOptions)}}
    options["report"] = args.report is not None
    verb.diagnose(**options).write(args.out, report=args.report)
    code = 0
    total = (time.perf_counter() - START[0], time.process_time() - START[1])
    rows = [("imports (the parser and oed.workflows.diagnose)", *IMPORTED)]
    rows += [(label, wall, cpu) for label, (wall, cpu) in SPENT.items()]
    print(f"{'phase':48s} {'wall s':>8s} {'CPU s':>8s} {'CPU share':>9s}", file=sys.stderr)
    for label, wall, cpu in rows + [("total (in process)", *total)]:
        print(f"{label:48s} {wall:8.2f} {cpu:8.2f} {cpu / total[1]:9.1%}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
