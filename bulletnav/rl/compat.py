"""Does a loaded model fit an env? Checked before any episode runs, so that a model of other
spaces is one clear error instead of an SB3 traceback in the middle of an episode."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import ModelError


def _describe(space: Any) -> str:
    """``Box of shape (62,)``: a space's kind and shape, short."""
    shape = getattr(space, "shape", None)
    return f"{type(space).__name__} of shape {shape}" if shape is not None else type(space).__name__


def space_mismatch(theirs: Any, ours: Any) -> str | None:
    """Why the space ``theirs`` (the model's) does not fit ``ours`` (the env's), or None.

    Spaces fit when they are of the same kind and shape, and a ``Box``'s bounds
    agree (to float32 precision: a model saved with float32 bounds fits its env's)."""
    if type(theirs) is not type(ours):
        return f"the model's is a {_describe(theirs)}, the env's a {_describe(ours)}"
    shape_a, shape_b = getattr(theirs, "shape", None), getattr(ours, "shape", None)
    if shape_a != shape_b:
        return f"the model's has shape {shape_a}, the env's {shape_b}"
    if hasattr(theirs, "low") and hasattr(theirs, "high"):
        for name in ("low", "high"):
            a = np.asarray(getattr(theirs, name), dtype=np.float64)
            b = np.asarray(getattr(ours, name), dtype=np.float64)
            diff = np.flatnonzero(~np.isclose(a, b, rtol=1e-6, atol=1e-6, equal_nan=True))  # inf == inf
            if diff.size:
                k = int(diff[0])
                return (f"both have shape {shape_a} but other bounds ({diff.size} differ): {name}[{k}] is "
                        f"{a.flat[k]:g} for the model, {b.flat[k]:g} for the env")
    elif theirs != ours:
        return f"the model's is {theirs}, the env's {ours}"
    return None


def check_model_fits(model: Any, env: Any, model_path: str | Path, env_id: str) -> None:
    """Raise :class:`~bulletnav.errors.ModelError` unless ``model`` (an SB3 model, or anything
    with ``observation_space`` and ``action_space``) was trained on spaces equal to ``env``'s.

    The message names the model file, the env id and both shapes, e.g.
    ``models/ppo_warehouse.zip does not fit bulletnav/WarehouseMission-v0: observation space:
    the model's has shape (46,), the env's (62,) (...)``.

    Args:
        model: the loaded model.
        env: the env (or vector env) it is to act in.
        model_path: the model's file, for the message.
        env_id: the env's id, for the message.
    """
    for name in ("observation_space", "action_space"):
        theirs, ours = getattr(model, name, None), getattr(env, name, None)
        if theirs is None or ours is None:
            continue
        why = space_mismatch(theirs, ours)
        if why is not None:
            raise ModelError(
                f"{model_path} does not fit {env_id}: {name.replace('_', ' ')}: {why} (a model runs on the env and "
                "settings it was trained with, which its .json records)")
