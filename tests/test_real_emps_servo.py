"""EMPS (real data, Janot, Gautier & Brunot): second-order force→position model of the axis, fitted on
DATA_EMPS.mat, validated on DATA_EMPS_PULSES.mat; compared with the published IDIM-LS values."""

from __future__ import annotations

from pathlib import Path

import pytest

from estimation.datasets.shared import load_emps
from estimation.datasets.emps_model import fit_emps_second_order, validate_emps

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "emps"
pytestmark = pytest.mark.realdata


@pytest.fixture(scope="module")
def records():
    if not (DATA / "DATA_EMPS.mat").is_file() or not (DATA / "DATA_EMPS_PULSES.mat").is_file():
        pytest.skip(f"EMPS data not found at {DATA} (shared data folder beside the checkout)")
    return load_emps(DATA, "estimation"), load_emps(DATA, which="validation")


def test_loader_gives_force_and_uniform_1khz_samples(records):
    estimation, validation = records
    assert estimation.qm.size == validation.qm.size == 24841
    assert estimation.dt == pytest.approx(1e-3, rel=1e-3)
    assert estimation.gtau == pytest.approx(35.15, rel=1e-3)
    assert estimation.pulses is None and validation.pulses is not None
    assert (estimation.force == estimation.gtau * estimation.vir).all()


def test_second_order_model_matches_published_values_and_validates(records):
    estimation, validation = records
    fit = fit_emps_second_order(estimation)
    # published IDIM-LS: M = 95.1 kg, Fv = 203.5 N s/m, Fc = 20.4 N, offset = -3.16 N
    assert fit.M == pytest.approx(95.1, rel=0.03)
    assert fit.Fv == pytest.approx(203.5, rel=0.03)
    assert fit.Fc == pytest.approx(20.4, rel=0.05)
    assert fit.offset == pytest.approx(-3.16, abs=0.3)
    check = validate_emps(fit, validation)
    print(f"\nEMPS fit M={fit.M:.2f} Fv={fit.Fv:.1f} Fc={fit.Fc:.2f} off={fit.offset:.2f}; validation force RMSE "
          f"{check.force_rmse:.2f} N (R2adj {check.force_r2_adj:.4f}), free-run position RMSE "
          f"{1e3 * check.position_rmse_free_run:.2f} mm (R2adj {check.position_r2_adj_free_run:.4f})")
    assert check.force_r2_adj > 0.95
    assert check.position_r2_adj_free_run > 0.95
