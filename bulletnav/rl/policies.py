"""SB3 policy classes with the lidar :class:`~bulletnav.rl.features.ClearanceFeatures` as
their default features extractor.

They let a hyperparameter file name the project's network in RL Zoo's own form
(``policy: bulletnav.rl.policies.ClearanceActorCriticPolicy``, plain ``policy_kwargs``), so
one file serves ``bulletnav train`` and ``python -m rl_zoo3.train`` alike: RL Zoo imports a
dotted ``policy`` but cannot resolve a class named inside ``policy_kwargs``. Each builds
exactly the network of the base class given ``features_extractor_class=ClearanceFeatures``.
"""

from __future__ import annotations

from typing import Any

from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.sac.policies import SACPolicy
from stable_baselines3.td3.policies import TD3Policy

from bulletnav.rl.features import ClearanceFeatures


class ClearanceActorCriticPolicy(ActorCriticPolicy):
    """PPO's and A2C's ``MlpPolicy`` on :class:`ClearanceFeatures`."""

    def __init__(self, *args: Any, features_extractor_class: type = ClearanceFeatures, **kwargs: Any) -> None:
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)


class ClearanceSACPolicy(SACPolicy):
    """SAC's ``MlpPolicy`` on :class:`ClearanceFeatures`."""

    def __init__(self, *args: Any, features_extractor_class: type = ClearanceFeatures, **kwargs: Any) -> None:
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)


class ClearanceTD3Policy(TD3Policy):
    """TD3's ``MlpPolicy`` on :class:`ClearanceFeatures`."""

    def __init__(self, *args: Any, features_extractor_class: type = ClearanceFeatures, **kwargs: Any) -> None:
        super().__init__(*args, features_extractor_class=features_extractor_class, **kwargs)
