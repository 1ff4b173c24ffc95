"""The env a command runs on: its id checked, its world options turned into ``gym.make``'s kwargs."""

from __future__ import annotations

import argparse

from bulletnav.cli.args import DEFAULT_ENV_ID
from bulletnav.errors import BulletnavError


def bulletnav_env_ids() -> list[str]:
    """The Gymnasium ids that bulletnav registers (``bulletnav/...``)."""
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the envs)

    return sorted(env_id for env_id in gym.registry if env_id.startswith("bulletnav/"))


def check_env_id(env_id: str) -> None:
    """Raise :class:`BulletnavError` naming ``env_id`` and the known ids unless bulletnav registers it."""
    ids = bulletnav_env_ids()
    if env_id not in ids:
        raise BulletnavError(f"unknown env id {env_id!r}; bulletnav env ids: {', '.join(ids)}")


def world_kwargs(args: argparse.Namespace, obstacles: int | None = None) -> dict:
    """``num_obstacles`` (``--obstacles``, else ``obstacles`` when given) and ``world`` (``--world``) for gym.make."""
    kwargs = {}
    if args.obstacles is not None:
        obstacles = args.obstacles
    if obstacles is not None:
        kwargs["num_obstacles"] = obstacles
    if args.world:
        kwargs["world"] = args.world
    if getattr(args, "goals", None) is not None:  # a mission of K goals on any env
        kwargs.update(task_name="mission", goals=args.goals)
    if getattr(args, "order", None) is not None:
        kwargs.update(task_name="mission", goal_order=args.order)
    if getattr(args, "perturb", None) is not None:  # a named evaluation shift, on any env and controller
        kwargs["perturb"] = args.perturb
    if getattr(args, "physics", None) is not None:  # a named physics profile
        kwargs["physics"] = args.physics
    return kwargs


def world_label(args: argparse.Namespace, obstacles: int | None = None) -> str:
    """The report's name of the warehouses: the layout file, or the procedural obstacle count."""
    if args.world:
        return args.world
    if args.obstacles is not None:
        obstacles = args.obstacles
    if obstacles is None and args.env_id == DEFAULT_ENV_ID:
        from bulletnav.config import WorldConfig

        obstacles = WorldConfig().num_obstacles
    return f"procedural ({obstacles} obstacles)" if obstacles is not None else "procedural"


def make_env(args: argparse.Namespace, **extra):
    """``gym.make`` of ``--env`` with the world options (and ``extra``); the GUI with ``--gui``."""
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the env)

    kwargs = dict(world_kwargs(args), **extra)
    if getattr(args, "layout_style", None):
        kwargs["layout_style"] = args.layout_style
    return gym.make(args.env_id, render_mode="human" if getattr(args, "gui", False) else None, **kwargs)


def shielded(args: argparse.Namespace, env):
    """``env`` behind the safety shield (``--shield``), else itself."""
    if not getattr(args, "shield", False):
        return env
    from bulletnav.control.shield import ShieldWrapper

    return ShieldWrapper(env)


def fleet_world_kwargs(args: argparse.Namespace, env_id: str | None) -> dict:
    """The fleet env's world arguments: ``env_id`` (``--env``: its registered settings instead of
    the fleet's aisle warehouse), ``--world``, ``--layout-style``, ``--obstacles``."""
    kwargs: dict = {}
    if env_id is not None:
        import gymnasium as gym

        from bulletnav.envs.warehouse import make_config

        kwargs["config"] = make_config(None, **gym.spec(env_id).kwargs)
    if args.world:
        kwargs["world"] = args.world
    if getattr(args, "layout_style", None):
        kwargs["layout_style"] = args.layout_style
    if args.obstacles is not None:
        kwargs["num_obstacles"] = args.obstacles
    return kwargs
