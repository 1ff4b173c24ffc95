"""Curriculum learning: training moves through stages of episodes as its success rate allows.

Declared in a hyperparameter entry (next to ``randomize:``)::

    curriculum:
      window: 50          # episodes the success rate is measured over
      promote: 0.8        # next stage when the rate over the last `window` episodes reaches this
      demote: 0.2         # optional: previous stage when it falls below this
      min_episodes: 50    # episodes in a stage before it may change (at least `window`)
      stages:             # env kwargs of each stage (WarehouseEnv.STAGE_KWARGS), easiest first
        - {forklifts: 0, workers: 0, pallet_events_per_min: 0, max_goal_distance: 5.0}
        - {forklifts: [1, 2], workers: [1, 3], forklift_speed: [0.3, 0.6]}
        - {}              # the env as made: the target distribution

:class:`Curriculum` is the decision (a success stream in, stage changes out);
:class:`CurriculumCallback` feeds it the training episodes' ``is_success``, sends a stage to
every sub-process env with ``env_method("set_episode_config", ...)`` (no env is rebuilt), logs
``curriculum/stage`` and ``curriculum/success_rate`` to TensorBoard and the console, and
gives its state to the checkpoint so ``--resume`` continues in the same stage.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

log = logging.getLogger(__name__)


@dataclass
class Curriculum:
    """Stage bookkeeping (see the module docstring). ``stages`` are env-kwarg mappings."""

    stages: list[dict[str, Any]]
    window: int = 50
    promote: float = 0.8
    demote: float | None = None
    min_episodes: int = 50
    stage: int = 0
    """The current stage (0 = the first, easiest)."""
    episodes_in_stage: int = 0
    recent: deque = field(default_factory=deque)
    changed_at_rate: float | None = None
    """The success rate that made the last stage change."""

    def __post_init__(self) -> None:
        self.recent = deque(self.recent, maxlen=self.window)

    @classmethod
    def from_spec(cls, spec: Mapping[str, Any], where: str = "curriculum") -> Curriculum:
        """Parse a ``curriculum:`` block.

        Raises:
            ValueError: a missing or malformed field, naming ``where`` and the field; a stage
                keyword the env cannot change between episodes.
        """
        from bulletnav.envs.warehouse import STAGE_KWARGS

        if not isinstance(spec, Mapping):
            raise ValueError(f"{where} must be a mapping with stages, window, promote, got {spec!r}")
        unknown = sorted(set(spec) - {"stages", "window", "promote", "demote", "min_episodes"}, key=str)
        if unknown:
            raise ValueError(f"{where}: unknown field(s) {', '.join(map(str, unknown))}; "
                             "known: demote, min_episodes, promote, stages, window")
        stages = spec.get("stages")
        if not isinstance(stages, list) or len(stages) < 2 or not all(isinstance(s, Mapping) for s in stages):
            raise ValueError(f"{where}.stages must be a list of at least 2 env-kwarg mappings, got {stages!r}")
        for i, stage in enumerate(stages):
            bad = sorted(set(stage) - STAGE_KWARGS, key=str)
            if bad:
                raise ValueError(f"{where}.stages[{i}]: {', '.join(map(str, bad))} cannot change between episodes; "
                                 f"allowed: {', '.join(sorted(STAGE_KWARGS))}")
        window = spec.get("window", 50)
        min_episodes = spec.get("min_episodes", window)
        promote, demote = spec.get("promote", 0.8), spec.get("demote")
        if not (isinstance(window, int) and window >= 1):
            raise ValueError(f"{where}.window must be an integer >= 1, got {window!r}")
        if not (isinstance(min_episodes, int) and min_episodes >= window):
            raise ValueError(f"{where}.min_episodes must be an integer >= window ({window}), got {min_episodes!r}")
        if not (isinstance(promote, (int, float)) and 0.0 < promote <= 1.0):
            raise ValueError(f"{where}.promote must be a success rate in (0, 1], got {promote!r}")
        if demote is not None and not (isinstance(demote, (int, float)) and 0.0 <= demote < promote):
            raise ValueError(f"{where}.demote must be a success rate below promote ({promote}), got {demote!r}")
        return cls([dict(s) for s in stages], window, float(promote), None if demote is None else float(demote),
                   min_episodes)

    @property
    def success_rate(self) -> float | None:
        """Success rate over the last ``window`` episodes of this stage (None before any)."""
        return sum(self.recent) / len(self.recent) if self.recent else None

    def record(self, success: bool) -> int | None:
        """Count one finished episode; the new stage when this one changes it, else None."""
        self.recent.append(bool(success))
        self.episodes_in_stage += 1
        if self.episodes_in_stage < self.min_episodes or len(self.recent) < self.window:
            return None
        rate = self.success_rate
        if rate >= self.promote and self.stage < len(self.stages) - 1:
            return self._move(self.stage + 1)
        if self.demote is not None and rate < self.demote and self.stage > 0:
            return self._move(self.stage - 1)
        return None

    def _move(self, stage: int) -> int:
        self.changed_at_rate = self.success_rate
        self.stage, self.episodes_in_stage = stage, 0
        self.recent.clear()
        return stage

    def state(self) -> dict[str, Any]:
        """What a checkpoint keeps: stage, episodes in it, the recent outcomes."""
        return {"stage": self.stage, "episodes_in_stage": self.episodes_in_stage, "recent": [int(r) for r in self.recent]}

    def restore(self, state: Mapping[str, Any]) -> None:
        self.stage = int(state["stage"])
        if not 0 <= self.stage < len(self.stages):
            raise ValueError(f"checkpoint curriculum stage {self.stage} is outside the {len(self.stages)} stages declared")
        self.episodes_in_stage = int(state["episodes_in_stage"])
        self.recent = deque((bool(r) for r in state["recent"]), maxlen=self.window)


class CurriculumCallback(BaseCallback):
    """Feeds training episodes to a :class:`Curriculum` and applies its stage changes."""

    def __init__(self, curriculum: Curriculum) -> None:
        super().__init__()
        self.curriculum = curriculum

    def send_stage(self, venv: Any) -> None:
        """Set the current stage in every env of ``venv`` (before training starts, and at each change)."""
        venv.env_method("set_episode_config", **self.curriculum.stages[self.curriculum.stage])

    def _announce(self, what: str) -> None:
        stage = self.curriculum.stages[self.curriculum.stage]
        log.info("curriculum: %s of %d: %s", what, len(self.curriculum.stages), stage or "the env as made")
        self.logger.record("curriculum/stage", self.curriculum.stage)

    def _on_training_start(self) -> None:  # the stage was sent before the envs' first reset
        self._announce(f"training starts in stage {self.curriculum.stage}")

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if not done:
                continue
            previous = self.curriculum.stage
            new = self.curriculum.record(bool(info.get("is_success", False)))
            if new is not None:
                verb = "promoted" if new > previous else "demoted"
                self.send_stage(self.training_env)
                self._announce(f"{verb} to stage {new} at {self.num_timesteps} steps (success "
                               f"{self.curriculum.changed_at_rate:.2f} over the last {self.curriculum.window} episodes)")
        rate = self.curriculum.success_rate
        if rate is not None:
            self.logger.record("curriculum/success_rate", rate)
        self.logger.record("curriculum/stage", self.curriculum.stage)
        return True
