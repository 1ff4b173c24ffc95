"""Model files: loading any saved model with clear errors, and saving an SB3 model and its
normalization statistics (through :mod:`bulletnav.files`, atomically).

This module sits above :mod:`bulletnav.rl.safe` (the safe format) and
:mod:`bulletnav.rl.sidecar` (the files beside a model) and imports them one way."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

from bulletnav.errors import ModelError
from bulletnav.filekinds import wrong_kind
from bulletnav.files import write_bytes, write_json
from bulletnav.rl import safe
from bulletnav.rl.algos import algo_class
from bulletnav.rl.sidecar import guess_algo, read_sidecar


def atomic_save_model(model, path: str | Path) -> None:
    """Save an SB3 model zip atomically (its bytes through :func:`bulletnav.files.write_bytes`)."""
    buffer = io.BytesIO()
    model.save(buffer)
    write_bytes(path, buffer.getvalue())


def atomic_save_vecnormalize(vecnorm, path: str | Path) -> None:
    """Write a ``VecNormalize``'s statistics as JSON (``model_vecnormalize.json``), atomically:
    numbers only, never a pickle."""
    write_json(path, safe.stats_to_json(vecnorm))


RUN_MODEL = "model.zip"
"""The model file ``bulletnav train --out RUN`` writes in its run directory."""


def model_file(path: str | Path) -> Path:
    """The model file ``path`` names: the file itself, or ``RUN/model.zip`` for a run directory
    that ``bulletnav train`` wrote (every ``--model`` takes either).

    Raises:
        ModelError: a folder without ``model.zip``.
    """
    path = Path(path)
    if path.is_dir():
        inner = path / RUN_MODEL
        if not inner.is_file():
            raise ModelError(f"{path}: a folder without a {RUN_MODEL} (bulletnav train writes RUN/{RUN_MODEL}; give "
                             "that file or the run folder that holds it)")
        return inner
    return path


def load_model(path: str | Path, algo: str | None = None, trust_pickle: bool = False):
    """Load a model saved by ``bulletnav train`` (or any SB3 zip; or the run directory that holds
    ``model.zip``, :func:`model_file`) without running code it holds.

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
    path = model_file(path)
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
        raise ModelError(wrong_kind(path, "model")
                         or f"{path}: not a model archive (not a zip file; truncated or another kind of file?)")
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

