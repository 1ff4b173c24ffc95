"""The Stable-Baselines3 algorithms ``train`` and ``evaluate`` know."""

from __future__ import annotations

ALGOS = ("ppo", "sac", "td3", "a2c")


def algo_class(name: str) -> type:
    """The SB3 class of ``name`` (``ppo``, ``sac``, ``td3``, ``a2c``).

    Raises:
        ValueError: unknown name.
    """
    from stable_baselines3 import A2C, PPO, SAC, TD3

    try:
        return {"ppo": PPO, "sac": SAC, "td3": TD3, "a2c": A2C}[name]
    except KeyError:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {', '.join(ALGOS)}") from None
