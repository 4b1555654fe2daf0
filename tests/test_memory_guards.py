"""Memory guards: a request sized past the machine's memory is refused before allocating."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from dynamics.runtime.memory import InsufficientMemoryError, available_memory, check_allocation, total_memory
from dynamics.models import build_model
from dynamics.robots import load_robot


def test_machine_memory_is_read():
    assert 0 < available_memory() <= total_memory() * 1.01


def test_check_allocation_refuses_beyond_the_limit_and_names_the_request():
    check_allocation(1e6, "a small array", limit=10**9)
    with pytest.raises(InsufficientMemoryError, match="a huge array needs about 9.31 GiB"):
        check_allocation(1e10, "a huge array", limit=10**9)
    with pytest.raises(InsufficientMemoryError):
        check_allocation(float("nan"), "nothing sensible")
    assert issubclass(InsufficientMemoryError, ValueError) and issubclass(InsufficientMemoryError, MemoryError)


def test_design_constraint_points_capped_at_a_period_and_cost_samples_guarded():
    from oed.excitation import DesignSettings
    from oed.design_problem import ExcitationDesign
    from oed.bounds import PUMA_BOUNDS

    with pytest.raises(ValueError, match="more than the 5000 samples of one period"):
        DesignSettings(constraint_points=1_000_000_000)
    DesignSettings(constraint_points=5000)
    robot = load_robot("puma560", joints=3)
    problem = ExcitationDesign(robot, "combined", PUMA_BOUNDS, settings=DesignSettings(cost_samples=10**11, jit=False))
    with pytest.raises(InsufficientMemoryError, match="cost_samples = 100000000000"):
        problem.cost_function()


def test_cli_design_constraint_points_refused_quickly(tmp_path):
    out = tmp_path / "design.json"
    run = subprocess.run([sys.executable, "-m", "oed", "design", "--joints", "3", "--constraint-points", "1000000000",
                          "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2, run.stderr
    assert "constraint_points = 1000000000" in run.stderr
    assert not out.exists()


def test_simulator_sample_count_guarded(monkeypatch):
    import dynamics.runtime.memory
    from dynamics.simulation.simulator import Simulator

    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 10**6)
    simulator = Simulator(load_robot("puma560", joints=3))
    with pytest.raises(InsufficientMemoryError, match="10 s at 1000 Hz"):
        simulator.run(lambda t: (np.zeros((len(t), 3)),) * 3, duration=10.0)


def test_aprbs_length_guarded(monkeypatch):
    import dynamics.runtime.memory
    from oed.aprbs_signal import APRBSDesign

    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 10**6)
    with pytest.raises(InsufficientMemoryError, match="an APRBS of 600"):
        APRBSDesign(duration=600.0, dt=0.001)


def test_streaming_chunk_size_guarded():
    from estimation.estimators.normal_equations import check_chunk_size

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    assert check_chunk_size(10_000, model) == 10_000
    with pytest.raises(InsufficientMemoryError, match="a chunk of 100000000000 samples"):
        check_chunk_size(10**11, model)
    with pytest.raises(ValueError, match="positive integer"):
        check_chunk_size(0, model)


def test_cli_identify_in_memory_refused_past_the_memory_with_a_hint(tmp_path, monkeypatch, capsys):
    import dynamics.runtime.memory
    from oed.cli import main
    from dynamics.simulation.synthetic import simulate, true_parameters

    from oed.fourier import random_fourier

    model = build_model(load_robot("puma560", joints=3), "internal", "viscous")
    data = simulate(model, true_parameters(model), random_fourier(model.robot, 1), noise={"tau1": 0.1, "tau2": 0.1,
                                                                                          "tau3": 0.1})
    path = tmp_path / "data.csv"
    data.write(path)
    out = tmp_path / "out.json"
    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 10**5)
    assert main(["identify", "--joints", "3", "--data", str(path), "--out", str(out)]) == 2
    assert "use --chunk-size" in capsys.readouterr().err and not out.exists()
    monkeypatch.setattr(dynamics.runtime.memory, "available_memory", lambda: 10**9)
    assert main(["identify", "--joints", "3", "--data", str(path), "--chunk-size", "500", "--out", str(out)]) == 0


def test_a_container_limit_bounds_the_available_memory(tmp_path, monkeypatch):
    import dynamics.runtime.memory

    limit, usage = tmp_path / "memory.max", tmp_path / "memory.current"
    limit.write_text("1073741824\n")
    usage.write_text("268435456\n")
    monkeypatch.setattr(dynamics.runtime.memory, "CGROUP_FILES", ((str(limit), str(usage)),))
    monkeypatch.setattr(dynamics.runtime.memory, "_meminfo", lambda key: 16 * 1024**3)
    assert available_memory() == 768 * 1024**2  # the container's room, not the host's 16 GiB
    limit.write_text("max\n")
    assert available_memory() == 16 * 1024**3
