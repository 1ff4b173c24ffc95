"""Property-based tests of the model loader (``bulletnav.rl.io.load_model``): a shipped model
with its sidecar, statistics or SB3 ``data`` mutated at random gives a model or a
:class:`~bulletnav.errors.ModelError`, never another exception, and never runs a payload.

Examples per property (``ci`` profile, derandomized; 20x under ``make fuzz``) in each docstring.
"""

from __future__ import annotations

import base64
import copy
import json
import pickle
import shutil
import tempfile
import zipfile
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from bulletnav.errors import ModelError
from bulletnav.rl.io import load_model
from fuzz_strategies import examples

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = json.loads((ROOT / "models" / "ppo_warehouse.json").read_text())
with zipfile.ZipFile(ROOT / "models" / "ppo_warehouse.zip") as _z:
    DATA = json.loads(_z.read("data"))

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True, allow_infinity=True),
              st.text(max_size=30), st.sampled_from(["os.system", "inf", "-inf", "Box", "float32", "<class 'dict'>"])),
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=10), inner, max_size=5)),
    max_leaves=12)


def _paths(doc, prefix=()):
    """Every path to a value inside a JSON document."""
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:4]):
            yield from _paths(v, (*prefix, i))


SIDECAR_PATHS = [p for p in _paths(SHIPPED) if p]
DATA_PATHS = [p for p in _paths(DATA) if p]


def _set(doc, path, value):
    doc = copy.deepcopy(doc)
    node = doc
    for part in path[:-1]:
        node = node[part]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


_DELETE = object()
mutation = st.one_of(json_values, st.just(_DELETE))


class _Payload:
    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _load_expecting_model_error(folder: Path, marker: Path) -> None:
    try:
        load_model(folder / "m.zip")
    except ModelError as exc:
        assert str(exc).strip()
    assert not marker.exists()


@settings(max_examples=examples(60), deadline=None)
@given(edits=st.lists(st.tuples(st.sampled_from(SIDECAR_PATHS), mutation), min_size=1, max_size=3))
def test_mutated_sidecars_load_or_give_a_model_error(edits):
    """examples: 60. Up to three fields of the safe sidecar (policy block, spaces, kwargs,
    hyperparameters, statistics) replaced by random JSON or deleted."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for suffix in (".zip", ".safetensors"):
            shutil.copy(ROOT / "models" / f"ppo_warehouse{suffix}", folder / f"m{suffix}")
        doc = SHIPPED
        for path, value in edits:
            try:
                doc = _set(doc, path, value)
            except (KeyError, IndexError, TypeError):
                continue  # an earlier edit removed or replaced the path
        (folder / "m.json").write_text(json.dumps(doc))
        _load_expecting_model_error(folder, folder / "never")


@settings(max_examples=examples(30), deadline=None)
@given(edits=st.lists(st.tuples(st.sampled_from(DATA_PATHS), st.one_of(mutation, st.just("PAYLOAD"))), min_size=1,
                      max_size=3))
def test_mutated_sb3_data_loads_or_gives_a_model_error_and_never_runs_a_payload(edits):
    """examples: 30. The zip alone (no safe files): up to three entries or fields of SB3's
    ``data`` replaced by random JSON, deleted, or given a pickled payload."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        marker = folder / "pwned"
        payload = {":type:": "<class 'dict'>", ":serialized:": base64.b64encode(pickle.dumps(_Payload(str(marker)))).decode()}
        doc = DATA
        for path, value in edits:
            try:
                doc = _set(doc, path, payload if value == "PAYLOAD" else value)
            except (KeyError, IndexError, TypeError):
                continue
        with zipfile.ZipFile(ROOT / "models" / "ppo_warehouse.zip") as zin, zipfile.ZipFile(folder / "m.zip", "w") as zout:
            for item in zin.infolist():
                zout.writestr(item, json.dumps(doc).encode() if item.filename == "data" else zin.read(item.filename))
        (folder / "m.json").write_text(json.dumps({"algo": "ppo", "env_id": SHIPPED["env_id"]}))
        _load_expecting_model_error(folder, marker)


@settings(max_examples=examples(40), deadline=None)
@given(blob=st.binary(max_size=4096), name=st.sampled_from(["m_vecnormalize.json", "m_vecnormalize.npz", "m.safetensors"]))
def test_random_bytes_as_statistics_or_weights_give_a_model_error(blob, name):
    """examples: 40. Random bytes as the statistics (JSON or npz) or as the weights file."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        shutil.copy(ROOT / "models" / "ppo_warehouse.zip", folder / "m.zip")
        meta = {"algo": "ppo"} if name != "m.safetensors" else {**SHIPPED, "policy": {**SHIPPED["policy"], "weights_sha256": None}}
        (folder / "m.json").write_text(json.dumps(meta))
        (folder / name).write_bytes(blob)
        _load_expecting_model_error(folder, folder / "never")
