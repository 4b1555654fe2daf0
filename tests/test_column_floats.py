""":func:`estimation.data.loading.column_floats`, the streamed reader's conversion of a block's column: the values
``pd.to_numeric(column, errors="coerce").to_numpy(dtype=float)`` gives, bit for bit, whatever the column holds."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from estimation.data.loading import column_floats

COLUMNS = {
    "floats": pd.Series([0.1, -2.5e-300, 1e308, np.nan, -0.0, np.inf]),
    "float32": pd.Series(np.array([0.1, 3.3, -7.25], dtype=np.float32)),
    "integers": pd.Series([1, -3, 2**53 + 1]),
    "unsigned": pd.Series(np.array([0, 7, 2**64 - 1], dtype=np.uint64)),
    "text": pd.Series(["0.5", "1e-3", "nan", "abc", ""]),
    "mixed objects": pd.Series([1.5, "2.25", None, "x"], dtype=object),
    "booleans": pd.Series([True, False, True]),
    "nullable": pd.Series([1.5, None, 2.0], dtype="Float64"),
}


@pytest.mark.parametrize("name", COLUMNS)
def test_the_floats_are_to_numeric_s_bit_for_bit(name):
    column = COLUMNS[name]
    expected = pd.to_numeric(column, errors="coerce").to_numpy(dtype=float)
    found = column_floats(column)
    assert found.dtype == np.float64 and found.shape == expected.shape
    assert found.tobytes() == expected.tobytes()
