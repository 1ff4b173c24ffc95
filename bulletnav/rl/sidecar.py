"""The files beside a saved model and the sidecar that describes it: ``NAME.json`` (algorithm,
env settings, the safe format's blocks) and ``NAME_vecnormalize.json`` (normalization
statistics). Read here, below both :mod:`bulletnav.rl.safe` (the safe format) and
:mod:`bulletnav.rl.io` (loading any model), which import it one way."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bulletnav.errors import ModelError
from bulletnav.rl.algos import ALGOS


def sidecar_path(model_path: str | Path) -> Path:
    """``model.zip`` -> ``model.json``: the algorithm and env settings a model needs."""
    p = Path(model_path)
    return p.with_suffix(".json")


def vecnormalize_path(model_path: str | Path) -> Path:
    """``model.zip`` -> ``model_vecnormalize.json``: the normalisation statistics beside a model."""
    p = Path(model_path)
    return p.with_name(p.stem + "_vecnormalize.json")


def read_sidecar(model_path: str | Path) -> dict[str, Any]:
    """The sidecar ``model.json`` beside a model, or ``{}`` when there is none.

    Raises:
        ModelError: it is not valid JSON or not a JSON object.
    """
    side = sidecar_path(model_path)
    if not side.is_file():
        return {}
    try:
        meta = json.loads(side.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as exc:
        raise ModelError(f"{side}: model metadata is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise ModelError(f"{side}: model metadata must be a JSON object")
    return meta


def guess_algo(data: dict[str, Any]) -> str | None:
    """The algorithm an SB3 zip's ``data`` names in its policy class's module (its text only)."""
    text = json.dumps(data.get("policy_class", {}))
    for name in ALGOS:
        if f"{name}.policies" in text.lower():
            return name
    return None
