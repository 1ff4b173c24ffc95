"""The navigator's optional cautious plan (NavigatorConfig.shadow_margin): unknown cells near a
mapped obstacle count as occupied, free cells never do; and the option's bounds."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.control.navigator import Navigator, NavigatorConfig


def test_shadow_options_are_checked() -> None:
    with pytest.raises(ValueError, match="shadow_margin"):
        NavigatorConfig(shadow_margin=-0.1)
    with pytest.raises(ValueError, match="shadow_margin"):
        NavigatorConfig(shadow_margin=float("nan"))
    with pytest.raises(ValueError, match="shadow_slack"):
        NavigatorConfig(shadow_slack=0.9)
    assert NavigatorConfig().shadow_margin is None  # off unless asked for


def test_unknown_cells_near_an_obstacle_are_shadow_but_seen_free_ones_are_not() -> None:
    env = gym.make("bulletnav/BARN-v0", world_idx=0)
    try:
        _, info = env.reset(seed=0)
        nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar", shadow_margin=0.3))
        nav.reset(info)
        m = nav.mapper
        m.log_odds[:] = 0.0  # all unknown
        i, j = m.nx // 2, m.ny // 2
        m.log_odds[:, :j] = -m.l_max  # seen free: every cell below the obstacle's row (smaller y)
        m.log_odds[i, j] = m.l_max  # one obstacle cell
        grid = nav._shadow_grid(0.3)
        res = m.resolution
        reach = nav.inflation + nav.config.preferred_margin  # the wide berth the grid is inflated by
        # along +y (unknown): shadow to 0.3 m, then the berth; along -y (seen free): the berth only
        k_far = int(round((0.3 + reach) / res))  # a cell centre 0.3 m + berth away
        k_berth = int(round(reach / res))
        assert grid.occupied[i, j + k_far - 1]
        assert not grid.occupied[i, j + k_far + 2]
        assert grid.occupied[i, j - k_berth + 1]
        assert not grid.occupied[i, j - k_berth - 2]
        plain = nav.mapper.grid().inflate(reach).occupied
        assert np.all(plain <= grid.occupied)  # the cautious map only ever adds
    finally:
        env.close()
