"""The starts a shape search refines: one a valley of the cost over the grid, the lowest valleys first."""

from __future__ import annotations

import numpy as np

from estimation.estimators.shape_starts import valley_floors


def test_one_start_a_valley_lowest_first():
    grid = np.arange(1.0, 8.0)[:, None]
    costs = np.array([5.0, 3.0, 4.0, 6.0, 2.0, 2.5, 7.0])
    # 2.5 lies in the valley of 2.0, 3.0 in a valley of its own; 5.0 and 7.0 are not floors
    assert valley_floors(grid, costs, 3) == [4, 1]
    assert valley_floors(grid, costs, 1) == [4]


def test_a_point_whose_cost_is_not_finite_is_neither_a_start_nor_a_neighbour():
    grid = np.array([[0.1], [0.2], [0.3]])
    assert valley_floors(grid, np.array([3.0, np.inf, 1.0]), 3) == [2, 0]
    assert valley_floors(grid, np.array([np.nan, np.inf, 1.0]), 3) == [2]


def test_of_equal_costs_the_earlier_point_is_the_floor():
    grid = np.array([[1.0], [2.0], [3.0]])
    assert valley_floors(grid, np.array([1.0, 1.0, 5.0]), 3) == [0]


def test_neighbours_on_a_product_grid_are_the_next_values_of_every_parameter():
    values = np.array([0.01, 0.1, 1.0, 10.0])
    grid = np.array([[a, b] for a in values for b in values])
    # two basins: around (0.1, 0.1) and around (10, 10); a diagonal neighbour is a neighbour too
    costs = np.array([np.hypot(np.log10(a) + 1, np.log10(b) + 1) * np.hypot(np.log10(a) - 1, np.log10(b) - 1)
                      for a, b in grid])
    floors = valley_floors(grid, costs, 5)
    assert {tuple(grid[index]) for index in floors} == {(0.1, 0.1), (10.0, 10.0)}
    # the grid's order decides nothing but ties: reversed, the same points
    reverse = valley_floors(grid[::-1], costs[::-1], 5)
    assert {tuple(grid[::-1][index]) for index in reverse} == {(0.1, 0.1), (10.0, 10.0)}
