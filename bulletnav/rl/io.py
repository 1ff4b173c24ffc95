"""Files of a training run, written atomically (temporary file, then ``os.replace``), and
model loading with clear errors."""

from __future__ import annotations

import io
import json
import os
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
    """Write a ``VecNormalize``'s statistics as JSON (``model_vecnormalize.json``), atomically:
    numbers only, never a pickle."""
    from bulletnav.rl.safe import stats_to_json

    atomic_write_json(path, stats_to_json(vecnorm))


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


def load_model(path: str | Path, algo: str | None = None, trust_pickle: bool = False):
    """Load a model saved by ``bulletnav train`` (or any SB3 zip) without running code it holds.

    The safe format (``NAME.safetensors`` + ``NAME.json``, :mod:`bulletnav.rl.safe`) is
    preferred; an SB3 zip without it loads with every pickled entry rebuilt from its text, and
    normalization statistics come from JSON or ``.npz``. ``trust_pickle`` lets SB3 unpickle the
    zip and opens a ``NAME_vecnormalize.pkl``: that runs whatever code the files hold.

    Returns ``(model, meta, normalizer)``; ``normalizer`` normalizes observations as the
    ``VecNormalize`` the model was trained behind (``norm_obs``, ``normalize_obs``), or is None.

    Raises:
        ModelError: the file is missing, not a zip, truncated, not an SB3 model, or of another
            algorithm than its sidecar says.
        UnsafeModelError: it can only be opened by running its code (and ``trust_pickle`` is off).
    """
    from bulletnav.rl import safe

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"{path}: model file not found")
    meta = read_sidecar(path)
    if algo is not None and meta.get("algo") not in (None, algo):
        raise ModelError(f"{path}: cannot load as {algo.upper()} (its sidecar says {str(meta.get('algo')).upper()})")
    algo = algo or meta.get("algo")
    if safe.has_safe(path, meta):
        model = safe.load_safe(path, meta)
        return model, meta, safe.normalizer(safe.load_stats(path, meta))
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
    except (zipfile.BadZipFile, OSError, KeyError) as exc:
        raise ModelError(f"{path}: corrupt model archive ({exc})") from exc
    data = safe.read_zip_data(path)
    if algo is None:
        algo = guess_algo(data)
    if algo is None:
        raise ModelError(f"{path}: cannot tell the algorithm; pass --algo or keep the .json beside the model")
    cls = algo_class(algo)
    stats = safe.load_stats(path, meta, trust_pickle=trust_pickle)  # refused before any tensor is read
    try:
        model = safe.load_zip(path, cls, trust_pickle=trust_pickle)
    except ModelError:
        raise
    except Exception as exc:  # SB3 and torch raise many kinds on a mismatched, broken or hostile archive
        raise ModelError(f"{path}: cannot load as {algo.upper()} ({type(exc).__name__}: {str(exc)[:300]})") from None
    if not isinstance(model, cls):
        raise ModelError(f"{path}: expected a {algo.upper()} model, got {type(model).__name__}")
    return model, meta, safe.normalizer(stats)


def guess_algo(data: dict[str, Any]) -> str | None:
    """The algorithm an SB3 zip's ``data`` names in its policy class's module (its text only)."""
    text = json.dumps(data.get("policy_class", {}))
    for name in ALGOS:
        if f"{name}.policies" in text.lower():
            return name
    return None
