"""Episodes as Minari datasets, the offline-RL world's exchange format.

:class:`DatasetRecorder` wraps a single-robot env (outermost) and keeps every episode's
observations (the reset's and each step's), actions, rewards, terminations, truncations and the
infos' scalar fields (numbers and booleans present from the reset on); :meth:`DatasetRecorder.save`
writes them as a Minari dataset (``minari.create_dataset_from_buffers``, Arrow storage) under
``MINARI_DATASETS_PATH`` (Minari's own default without it), with the env's spec, so that
``minari.load_dataset(NAME).recover_environment()`` builds the same env again. Minari writes
the dataset's folder itself; a name that exists already is refused before any episode runs.

Behind a shield wrapper (``--shield``) the actions stored are those carried out: where the shield
replaced a command, its replacement, mapped onto the action space (the spec recovers the env
without the shield).
"""

from __future__ import annotations

import logging
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.errors import BulletnavError

log = logging.getLogger(__name__)



def dataset_exists(name: str) -> bool:
    """True when the local Minari store holds a dataset ``name``."""
    import minari

    return name in minari.list_local_datasets()


def check_name(name: str) -> str:
    """``name`` when it is a valid, unused dataset id, by Minari's own rule
    (``minari.dataset.minari_dataset.parse_dataset_id``, which ``minari.create_dataset_from_buffers``
    applies when the episodes are written): checked before any episode runs.

    Raises:
        BulletnavError: a malformed id, or one the local store already holds.
    """
    from minari.dataset.minari_dataset import parse_dataset_id

    try:
        _, _, version = parse_dataset_id(name)  # int(None) when the -vN is missing: TypeError
    except (ValueError, TypeError):
        version = None
    if version is None:
        raise BulletnavError(f"--dataset {name!r}: a Minari dataset id is [namespace/]name-vN (name: letters, digits, "
                             "'_' and '-'; namespace: 2 or more of them and '/'), e.g. bulletnav/aisles-astar-v0")
    if dataset_exists(name):
        from minari.storage.datasets_root_dir import get_dataset_path

        raise BulletnavError(f"--dataset {name}: the dataset already exists ({get_dataset_path(name)}); choose another "
                             "name or delete it with `minari delete " + name + "`")
    return name


def _scalars(info: dict[str, Any]) -> dict[str, float | bool]:
    out: dict[str, float | bool] = {}
    for key, value in info.items():
        if isinstance(value, (bool, np.bool_)):
            out[key] = bool(value)
        elif isinstance(value, (int, float, np.integer, np.floating)):
            out[key] = float(value)
    return out


class DatasetRecorder(gym.Wrapper):
    """Keep every episode of ``env`` for a Minari dataset (see the module docstring).

    Args:
        env: a single-robot bulletnav env made by ``gym.make`` (its spec is stored).
        name: the dataset id (checked by :func:`check_name`).
    """

    def __init__(self, env: gym.Env, name: str) -> None:
        super().__init__(env)
        if not isinstance(env.observation_space, gym.spaces.Box) or not isinstance(env.action_space, gym.spaces.Box):
            raise BulletnavError(f"--dataset {name}: datasets take vector observations and actions (Box spaces); this "
                                 f"env has {type(env.observation_space).__name__} observations (camera_obs must be off)")
        self.name = check_name(name)
        self.buffers: list[Any] = []
        self._current: dict[str, Any] | None = None
        self._keys: set[str] | None = None

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._flush()
        scalars = _scalars(info)
        self._current = {"seed": kwargs.get("seed"), "observations": [np.array(obs, copy=True)], "actions": [],
                         "rewards": [], "terminations": [], "truncations": [], "infos": [scalars]}
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        ep = self._current
        if ep is None:
            raise BulletnavError("DatasetRecorder: step() before reset()")
        ep["observations"].append(np.array(obs, copy=True))
        ep["actions"].append(self._executed(action, info))
        ep["rewards"].append(float(reward))
        ep["terminations"].append(bool(terminated))
        ep["truncations"].append(bool(truncated))
        ep["infos"].append(_scalars(info))
        if terminated or truncated:
            self._flush()
        return obs, reward, terminated, truncated, info

    def _executed(self, action: Any, info: dict[str, Any]) -> np.ndarray:
        """The action the env carried out: the shield's replacement where a shield wrapper
        (``info["shield"]``) replaced the command, mapped back onto the action space; else ``action``."""
        space = self.env.action_space
        veto = info.get("shield")
        if not (isinstance(veto, dict) and veto.get("intervened")):
            return np.array(action, dtype=space.dtype, copy=True)
        executed = self.env.unwrapped.scene.action_for(float(veto["v"]), float(veto["w"]))
        return np.clip(executed.astype(space.dtype, copy=False), space.low, space.high)

    def _flush(self) -> None:
        """Keep the episode under way, if it has a step (an episode cut short by a reset is kept as truncated)."""
        from minari.data_collector import EpisodeBuffer

        ep, self._current = self._current, None
        if ep is None or not ep["actions"]:
            return
        if not (ep["terminations"][-1] or ep["truncations"][-1]):
            ep["truncations"][-1] = True
        keys = set.intersection(*(set(i) for i in ep["infos"]))
        self._keys = keys if self._keys is None else self._keys & keys
        self.buffers.append(EpisodeBuffer(
            id=len(self.buffers), seed=ep["seed"], observations=np.stack(ep["observations"]),
            actions=np.stack(ep["actions"]), rewards=ep["rewards"], terminations=ep["terminations"],
            truncations=ep["truncations"],
            # plain lists: Minari 0.5.4's Arrow storage cannot read back a 1-D array's empty shape tag
            infos={k: [i[k] for i in ep["infos"]] for k in sorted(keys)}))

    def save(self, algorithm: str, description: str = "", author: str = "bulletnav") -> Any:
        """Write the episodes kept so far as the dataset; returns the ``MinariDataset``.

        Raises:
            BulletnavError: no complete episode, or the name was taken meanwhile.
        """
        import warnings

        import minari

        self._flush()
        if not self.buffers:
            raise BulletnavError(f"--dataset {self.name}: no complete episode to write")
        if dataset_exists(self.name):
            raise BulletnavError(f"--dataset {self.name}: the dataset appeared while the episodes ran; nothing written")
        keys = sorted(self._keys or ())
        buffers = [b if set(b.infos) == set(keys) else type(b)(
            id=b.id, seed=b.seed, observations=b.observations, actions=b.actions, rewards=b.rewards,
            terminations=b.terminations, truncations=b.truncations, infos={k: b.infos[k] for k in keys})
            for b in self.buffers]
        from bulletnav.provenance import git_commit

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # Minari's reminders of optional metadata
            dataset = minari.create_dataset_from_buffers(
                self.name, buffers, env=self.env.spec, algorithm_name=algorithm, author=author,
                code_permalink=f"bulletnav@{git_commit()}",
                description=description or f"{len(buffers)} episodes of {self.env.spec.id} driven by {algorithm}",
                data_format="arrow")
        log.info("wrote Minari dataset %s: %d episodes, %d steps", self.name, dataset.total_episodes, dataset.total_steps)
        return dataset


__all__ = ["DatasetRecorder", "check_name", "dataset_exists"]
