"""Gymnasium environments of sanlab's creatures (needs ``pip install 'sanlab[gym]'``).

Importing this module registers, with Gymnasium's registry, one environment per built-in
creature and one for any creature file:

    >>> import gymnasium
    >>> import sanlab.gym                                            # registers the ids below
    >>> env = gymnasium.make("sanlab/Bounder-v0")
    >>> env = gymnasium.make("sanlab/Creature-v0", path="my.toml")
    >>> envs = gymnasium.make_vec("sanlab/Bounder-v0", num_envs=64, vectorization_mode="vector_entry_point")

or, without importing it first, Gymnasium's module-prefix form, which imports it:
``gymnasium.make("sanlab.gym:sanlab/Bounder-v0")``.

Ids: ``sanlab/<Name>-v0`` for each built-in (:data:`ENV_IDS`: Bounder, Cart, Crawler, Fish,
Fourlink, Luxo, Star, Threelink, Twolink, Walker) and ``sanlab/Creature-v0`` (give ``path=`` a
creature file, or ``creature=`` a name or a ``Creature``). Each has an entry point (the single
environment, :class:`~sanlab.gym.env.SanlabEnv`) and a vector entry point (the batched one,
:class:`~sanlab.gym.vector.SanlabVectorEnv`); keywords of either go through ``make`` /
``make_vec``. No ``max_episode_steps`` is registered: an episode lasts the creature's evaluation
time, and the environments truncate it themselves. Spaces, reward and termination:
``sanlab.gym.env``; a SAN as a policy: ``sanlab.gym.policy``; docs/gymnasium.md.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from sanlab.creature import builtin_names
from sanlab.gym.env import SanlabEnv
from sanlab.gym.policy import SanPolicy, gait_env_kwargs
from sanlab.gym.vector import SanlabVectorEnv

ENTRY_POINT = "sanlab.gym.env:SanlabEnv"
VECTOR_ENTRY_POINT = "sanlab.gym.vector:SanlabVectorEnv"
CREATURE_ID = "sanlab/Creature-v0"
ENV_IDS: dict[str, str] = {f"sanlab/{name.capitalize()}-v0": name for name in builtin_names()}  # id -> built-in name


def _register() -> None:
    for env_id, name in ENV_IDS.items():
        if env_id not in registry:
            register(env_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT, kwargs={"creature": name})
    if CREATURE_ID not in registry:
        register(CREATURE_ID, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT)


_register()

__all__ = ["CREATURE_ID", "ENV_IDS", "SanPolicy", "SanlabEnv", "SanlabVectorEnv", "gait_env_kwargs"]
