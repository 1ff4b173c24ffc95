"""Gymnasium environments."""

from bulletnav.envs.warehouse import WarehouseEnv, make_config

__all__ = ["WarehouseEnv", "make_config"]
