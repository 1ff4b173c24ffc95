"""Files of a training run, written atomically (temporary file, then ``os.replace``), and
model loading with clear errors."""

from __future__ import annotations

import io
import json
import os
import pickle
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import ModelError
from bulletnav.rl.algos import ALGOS, algo_class


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``: a reader (or a
    crash) never sees a half-written file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; shipped files should be readable
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_save_model(model, path: str | Path) -> None:
    """Save an SB3 model zip atomically."""
    buffer = io.BytesIO()
    model.save(buffer)
    atomic_write_bytes(path, buffer.getvalue())


def atomic_save_vecnormalize(vecnorm, path: str | Path) -> None:
    """Pickle a ``VecNormalize`` (its statistics) atomically."""
    atomic_write_bytes(path, pickle.dumps(vecnorm))


def atomic_write_json(path: str | Path, data: Any) -> None:
    """Write ``data`` as indented JSON atomically (NumPy values and paths converted)."""
    atomic_write_bytes(path, (json.dumps(data, indent=2, default=_json_default) + "\n").encode())


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, type):
        return f"{o.__module__}.{o.__qualname__}"
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def sidecar_path(model_path: str | Path) -> Path:
    """``model.zip`` -> ``model.json``: the algorithm and env settings a model needs."""
    p = Path(model_path)
    return p.with_suffix(".json")


def vecnormalize_path(model_path: str | Path) -> Path:
    """``model.zip`` -> ``model_vecnormalize.pkl``: the normalisation statistics beside a model."""
    p = Path(model_path)
    return p.with_name(p.stem + "_vecnormalize.pkl")


def load_model(path: str | Path, algo: str | None = None):
    """Load a model saved by ``bulletnav train`` with its sidecar metadata.

    Returns ``(model, meta, vecnorm)``; ``vecnorm`` is the saved ``VecNormalize`` or None.

    Raises:
        ModelError: the file is missing, not a zip, truncated, not an SB3 model, or of another
            algorithm than its sidecar says.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: model file not found")
    meta: dict[str, Any] = {}
    side = sidecar_path(path)
    if side.is_file():
        try:
            meta = json.loads(side.read_text())
        except json.JSONDecodeError as exc:
            raise ModelError(f"{side}: model metadata is not valid JSON ({exc})") from exc
    algo = algo or meta.get("algo")
    if not zipfile.is_zipfile(path):
        raise ModelError(f"{path}: not a model archive (not a zip file; truncated or another kind of file?)")
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
            if "data" not in names or "policy.pth" not in names:
                raise ModelError(f"{path}: zip file is not a Stable-Baselines3 model (no 'data' / 'policy.pth')")
            bad = zf.testzip()
            if bad is not None:
                raise ModelError(f"{path}: corrupt model archive (member {bad!r} fails its CRC)")
            data = json.loads(zf.read("data"))
    except (zipfile.BadZipFile, OSError, json.JSONDecodeError, KeyError) as exc:
        raise ModelError(f"{path}: corrupt model archive ({exc})") from exc
    if algo is None:
        algo = _guess_algo(data)
    if algo is None:
        raise ModelError(f"{path}: cannot tell the algorithm; pass --algo or keep the .json beside the model")
    cls = algo_class(algo)
    try:
        model = cls.load(path, device="cpu")
    except Exception as exc:  # SB3 raises many kinds on a mismatched or broken archive
        raise ModelError(f"{path}: cannot load as {algo.upper()} ({type(exc).__name__}: {exc})") from exc
    if not isinstance(model, cls):
        raise ModelError(f"{path}: expected a {algo.upper()} model, got {type(model).__name__}")
    vecnorm = None
    vn = vecnormalize_path(path)
    if vn.is_file():
        with open(vn, "rb") as f:
            vecnorm = pickle.load(f)
    return model, meta, vecnorm


def _guess_algo(data: dict[str, Any]) -> str | None:
    text = json.dumps(data.get("policy_class", {}))
    for name in ALGOS:
        if f"{name}.policies" in text.lower():
            return name
    return None
