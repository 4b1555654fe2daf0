"""The package fronts: each package's ``__init__`` names what users import, imported on first use."""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys

import pytest

import dynamics
import estimation
import oed

FRONTS = sorted({module.name for root in (dynamics, estimation, oed)
                 for module in pkgutil.walk_packages(root.__path__, root.__name__ + ".") if module.ispkg
                 and not module.name.startswith("oed.cli")} | {"dynamics", "estimation", "oed"})


@pytest.mark.parametrize("name", FRONTS)
def test_every_name_a_front_lists_is_importable_from_it(name):
    package = importlib.import_module(name)
    assert package.__all__, f"{name} names nothing users import"
    submodules = {module.name for module in pkgutil.iter_modules(package.__path__)}
    assert not set(package.__all__) & submodules  # a submodule imported later would hide the name
    for public in package.__all__:
        assert getattr(package, public) is not None
        assert public in dir(package)
    with pytest.raises(AttributeError, match="no attribute"):
        package.no_such_name  # noqa: B018


def test_the_documented_imports_work():
    from dynamics import build_model, load_robot
    from estimation.identification import identify

    model = build_model(load_robot("puma560", joints=2), "internal", "viscous")
    assert model.n_base > 0 and callable(identify)


def test_importing_the_fronts_imports_no_module_behind_them():
    code = ("import sys, dynamics, estimation, oed, estimation.identification, estimation.diagnosis, "
            "estimation.streaming, dynamics.simulation, oed.workflows; "
            "print(sorted(name for name in sys.modules if name.split('.')[0] in ('dynamics', 'estimation', 'oed')))")
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert eval(shown) == sorted(["dynamics", "estimation", "oed", "estimation.identification", "estimation.diagnosis",
                                  "estimation.streaming", "dynamics.simulation", "oed.workflows",
                                  "dynamics.runtime", "dynamics.runtime.lazy"])  # the fronts' one helper (no imports)


def test_a_name_in_two_fronts_means_one_thing_unless_it_is_a_verb():
    """``oed.identify`` (the verb, a run object) beside ``estimation.identification.identify`` (the estimate) is
    by design; any other name two fronts list is the same object."""
    meanings: dict[str, set[int]] = {}
    for name in FRONTS:
        package = importlib.import_module(name)
        for public in package.__all__:
            meanings.setdefault(public, set()).add(id(getattr(package, public)))
    shared = sorted(public for public, objects in meanings.items() if len(objects) > 1)
    assert set(shared) <= set(oed.VERB_FUNCTIONS), shared
