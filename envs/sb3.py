"""Stable-Baselines3 on navsim's native vector env: an SB3 ``VecEnv`` over a Gymnasium ``VectorEnv``.

Stable-Baselines3 (extra ``rl``) steps its own ``VecEnv`` type; Gymnasium 1.x vector envs,
navsim's native :class:`~navsim.envs.vector.NavigationVectorEnv` among them, have another
interface. :class:`GymnasiumVecEnv` translates:

=====================================  ==================================================
Gymnasium ``VectorEnv``                 SB3 ``VecEnv``
=====================================  ==================================================
``reset(seed=s)``: sub-env j seed s+j   ``seed(s)`` then ``reset()``: the same seeds
``step`` -> obs, r, term, trunc, info   ``step`` -> obs, r, done, infos (a list of dicts)
info: a dict of arrays with ``_key``    ``infos[j]``: the keys set for sub-env j
masks
an episode that ends: NEXT_STEP         SB3's convention: ``done[j]`` with the *next*
autoreset (the following step resets)   episode's first observation, the last one in
                                        ``infos[j]["terminal_observation"]``;
                                        ``infos[j]["TimeLimit.truncated"]`` for
                                        bootstrapping a time limit
=====================================  ==================================================

Episodes that end together (the native navigation env runs its members in lockstep: they
all truncate at the scenario's end) are reset at once with the next seeds of the vector
env's own generator. An env with ``autoreset_mode`` SAME_STEP is passed through (its
``final_obs`` becomes ``terminal_observation``); with DISABLED, the ended members are
reset with a ``reset_mask``. A NEXT_STEP env whose members end at different steps is
refused (its next step would reset some members and step the others on one action).

Use::

    from stable_baselines3 import PPO
    from navsim.envs.sb3 import make_sb3_vec_env

    venv = make_sb3_vec_env("navsim/PaperRail-v0", num_envs=64, score=False, timing={"duration_s": 60.0})
    PPO("MultiInputPolicy", venv).learn(10_000)

The two task ids (``navsim/AdaptiveFilter-v0``, ``navsim/TrainDriving-v0``) have no
native vector env: their cost per step is the attached estimator (one filter per
member, each its own Python object stepping its own interval; the shared truth that makes
the navigation ids fast is a small part of a task step), and in the driving task every
member's truth follows its own driver (external motion), so members cannot share one
truth at all. ``make_sb3_vec_env`` gives them SB3's ``make_vec_env`` (a ``DummyVecEnv``,
or ``SubprocVecEnv`` with ``vec_env_cls``) instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NoReturn, Sequence, SupportsIndex

import numpy as np

try:
    from stable_baselines3.common.vec_env import VecEnv
except ImportError:  # the rl extra is optional
    from navsim.errors import DependencyNotInstalled

    raise DependencyNotInstalled("stable-baselines3", "rl") from None

if TYPE_CHECKING:  # type hints only
    from gymnasium.vector import VectorEnv

__all__ = ["GymnasiumVecEnv", "make_sb3_vec_env"]

Obs = np.ndarray | dict[str, np.ndarray]
"""An observation batch: one array, or a dict of arrays for dict spaces (SB3's VecEnvObs)."""
Indices = int | Sequence[int] | None
"""Sub-env indices as SB3 passes them (None: all)."""


def _writable(obs: Any) -> Obs:
    """A copy of the native env's read-only views (PyTorch refuses non-writable arrays)."""
    if isinstance(obs, dict):
        return {key: np.array(value) for key, value in obs.items()}
    return np.array(obs)


def _index(obs: Any, j: SupportsIndex) -> Obs:
    if isinstance(obs, dict):
        return {key: np.array(value[j]) for key, value in obs.items()}
    return np.array(obs[j])


class GymnasiumVecEnv(VecEnv):
    """An SB3 ``VecEnv`` stepping a Gymnasium 1.x ``VectorEnv`` (see the module docstring).

    Parameters
    ----------
    venv : gymnasium.vector.VectorEnv
        E.g. ``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``.
    """

    def __init__(self, venv: VectorEnv) -> None:
        from gymnasium.vector import AutoresetMode

        self.venv = venv
        mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        self.autoreset_mode = AutoresetMode(mode) if isinstance(mode, str) else mode
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._next_seed: int | None = None
        self._rng = np.random.default_rng()

    # ------------------------------------------------------------------ SB3 interface
    def seed(self, seed: int | None = None) -> list[int | None]:
        """Seeds ``seed + j`` for sub-env j at the next ``reset()`` (as Gymnasium's vector reset)."""
        super().seed(seed)
        self._next_seed = None if seed is None else int(seed)
        self._rng = np.random.default_rng(seed)
        return [None if seed is None else int(seed) + j for j in range(self.num_envs)]

    def reset(self) -> Obs:
        seed = self._next_seed
        if seed is None:
            seed = int(self._rng.integers(0, 2**31 - 1))
        self._next_seed = None
        options = self._options[0] if self._options and self._options[0] else None
        obs, info = self.venv.reset(seed=seed, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = self._split_info(info)
        return _writable(obs)

    def step_async(self, actions: np.ndarray) -> None:
        from .spaces import check_action

        shape = (self.num_envs, *self.action_space.shape)
        self._actions = check_action(actions, shape, f"an array of shape {shape} of real numbers", name="actions")

    def step_wait(self) -> tuple[Obs, np.ndarray, np.ndarray, list[dict]]:
        from gymnasium.vector import AutoresetMode

        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        infos = self._split_info(info)
        dones = np.logical_or(terminated, truncated)
        for j in np.flatnonzero(dones):
            infos[j]["TimeLimit.truncated"] = bool(truncated[j] and not terminated[j])
        if dones.any():
            if self.autoreset_mode == AutoresetMode.SAME_STEP:
                for j in np.flatnonzero(dones):
                    infos[j]["terminal_observation"] = _index(info["final_obs"], j)
                    infos[j].pop("final_obs", None)
                    infos[j].pop("final_info", None)
            else:
                for j in np.flatnonzero(dones):
                    infos[j]["terminal_observation"] = _index(obs, j)
                if dones.all():
                    seed = int(self._rng.integers(0, 2**31 - 1))
                    obs, reset_info = self.venv.reset(seed=seed)
                elif self.autoreset_mode == AutoresetMode.DISABLED:
                    obs, reset_info = self.venv.reset(options={"reset_mask": dones})
                else:
                    raise NotImplementedError("GymnasiumVecEnv: a NEXT_STEP vector env whose sub-envs end at "
                                              "different steps (its next step would reset only some of them)")
                self.reset_infos = self._split_info(reset_info)
        return _writable(obs), np.asarray(rewards, dtype=np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Indices = None) -> list[Any]:
        value = getattr(self.venv.unwrapped if hasattr(self.venv, "unwrapped") else self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Indices = None) -> None:
        setattr(self.venv.unwrapped if hasattr(self.venv, "unwrapped") else self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Indices = None,
                   **method_kwargs: Any) -> list[Any]:
        target = self.venv.unwrapped if hasattr(self.venv, "unwrapped") else self.venv
        result = getattr(target, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Indices = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> NoReturn:
        raise NotImplementedError("the native vector env does not render; render a single env "
                                  "(render_mode='rgb_array')")

    # ------------------------------------------------------------------ helpers
    def _split_info(self, info: dict) -> list[dict]:
        """Gymnasium's dict of arrays (with ``_key`` masks) -> one dict per sub-env."""
        out: list[dict] = [{} for _ in range(self.num_envs)]
        for key, value in info.items():
            if key.startswith("_"):
                continue
            mask = info.get(f"_{key}")
            for j in range(self.num_envs):
                if mask is None or bool(mask[j]):
                    out[j][key] = value[j] if hasattr(value, "__getitem__") and not isinstance(value, dict) \
                        else value
        return out


def make_sb3_vec_env(env_id: str, num_envs: int = 1, *, seed: int | None = None, **kwargs: Any) -> VecEnv:
    """An SB3 ``VecEnv`` for a navsim id: the native vector env (through
    :class:`GymnasiumVecEnv`) where the id has one, else SB3's ``make_vec_env``."""
    import gymnasium as gym

    spec = gym.spec(env_id)
    if spec.vector_entry_point is not None:
        venv = GymnasiumVecEnv(gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                                            **kwargs))
    else:
        from stable_baselines3.common.env_util import make_vec_env

        venv = make_vec_env(env_id, n_envs=num_envs, env_kwargs=kwargs)
    if seed is not None:
        venv.seed(seed)
    return venv
