"""The native vector env with ``threads=2``: the next chunk generated ahead on a thread of
its own (its IMU pass split over the batch's worker threads) changes no number."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import navsim.envs  # noqa: E402, F401  (registers the ids)
from navsim.envs.vector import NavigationVectorEnv  # noqa: E402
from navsim.simulator import IMU_GROUP  # noqa: E402

# more members than one IMU group, so that both worker threads take a run of groups
N = IMU_GROUP + 3
OVER = {"timing": {"duration_s": 1.5},
        "outages": {"windows_s": [[0.4, 0.9]], "receiver_mean_outage_s": 0.3, "receiver_mean_available_s": 0.5}}
# every IMU error term (Gauss-Markov, random walk, quantization: the NumPy path of the
# quantizer beside the compiled white-noise pass of the default preset)
MEMS = {"imu": {"preset": "consumer-mems"}}


def _same(a: dict, b: dict) -> bool:
    return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in a)


def _pair(chunk_steps: int, score: bool = True, extra: dict | None = None, threads: int = 2
          ) -> tuple[NavigationVectorEnv, NavigationVectorEnv]:
    over = {**OVER, **(extra or {})}
    one, two = (NavigationVectorEnv(N, "paper-2012", chunk_steps=chunk_steps, score=score, threads=t,
                                    reward_weights=(1.0, 0.5, 2.0), **over) for t in (1, threads))
    assert one._loader is None and two._loader is not None
    return one, two


def _step_both(one, two, actions) -> None:
    out1, out2 = one.step(actions), two.step(actions)
    assert _same(out1[0], out2[0])
    for a, b in zip(out1[1:4], out2[1:4]):
        assert np.array_equal(a, b)
    info1, info2 = out1[4], out2[4]
    assert set(info1) == set(info2)
    for key in info1:
        if key == "episode_score":
            assert [s.to_flat_dict() for s in info1[key]] == [s.to_flat_dict() for s in info2[key]]
        elif key not in ("context", "prior"):
            assert np.array_equal(info1[key], info2[key]), key


@pytest.mark.parametrize(("chunk_steps", "extra", "threads"), [(1, {}, 2), (37, {}, 2), (37, MEMS, 2), (37, {}, 3)],
                         ids=["chunk-1", "chunk-37", "mems", "three-threads"])
def test_two_threads_equal_one_thread_through_autoresets(chunk_steps, extra, threads):
    """Every member's observations, rewards, flags, infos and episode scores with threads=2
    are those of threads=1 (itself equal to the single envs: test_vector_render.py), over
    two episodes and their autoreset, with chunks that do not divide the episode (37
    steps) and with a chunk per step (no overlap: the next chunk is awaited at once)."""
    one, two = _pair(chunk_steps, extra=extra)
    obs1, _ = one.reset(seed=7)
    obs2, _ = two.reset(seed=7)
    assert _same(obs1, obs2)
    rng = np.random.default_rng(0)
    steps = one.n_steps
    for _ in range(2 * steps + 2):
        _step_both(one, two, rng.standard_normal((N, 9)))
    one.close()
    two.close()
    two.close()


def test_reset_and_close_while_a_chunk_is_generated_ahead():
    """A reset in the middle of a chunk (the next one being generated) discards the chunk
    generated ahead: the episode is that of a fresh env; close waits for the thread."""
    one, two = _pair(40, score=False)
    two.reset(seed=1)
    for _ in range(50):  # into the second chunk: the third is being generated
        two.step(np.zeros((N, 9)))
    assert two._next is not None
    obs2, _ = two.reset(seed=3)
    obs1, _ = one.reset(seed=3)
    assert _same(obs1, obs2)
    for _ in range(45):
        _step_both(one, two, np.zeros((N, 9)))
    assert two._next is not None
    two.close()
    assert two._next is None and two._loader is None
    one.close()


def test_chunks_generated_ahead_reuse_the_output_buffers():
    """The chunk generated ahead starts after the first step of the current chunk, when
    the caller holds only the current chunk's observations: it takes the buffers of the
    previous chunk (the pool of SimulatorBatch), so no chunk after the first two touches
    fresh memory unless the caller keeps an older observation."""
    chunk = 30
    venv = NavigationVectorEnv(N, "paper-2012", chunk_steps=chunk, score=False, threads=2, **OVER)
    venv.reset(seed=5)
    seen: list = []
    for _ in range(4 * chunk):
        venv.step(np.zeros((N, 9)))
        for bufs in venv.batch._pool:
            if not any(ref() is bufs[0] for ref in seen):
                seen.append(weakref.ref(bufs[0]))
    assert len(venv.batch._pool) == 2 and len(seen) == 2
    venv.close()


def test_first_use_in_a_fresh_process_with_threads():
    """The compiled kernels are made once even when the first chunk of a process is
    generated with threads (the IMU workers and the chunk thread reach
    ``navsim.sensors.imu.kernel`` at once: it used to hand one of them a half-filled table,
    a KeyError)."""
    import subprocess
    import sys

    code = ("import numpy as np\n"
            "from navsim.envs.vector import NavigationVectorEnv\n"
            f"env = NavigationVectorEnv({2 * IMU_GROUP}, 'paper-2012', threads=2, score=False, chunk_steps=50,\n"
            "                          timing={'duration_s': 2.0})\n"
            "env.reset(seed=0)\n"
            "for _ in range(120):\n"
            f"    env.step(np.zeros(({2 * IMU_GROUP}, 9)))\n"
            "env.close()\n"
            "print('ok')\n")
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
        assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_an_error_in_an_imu_group_reaches_the_caller(monkeypatch):
    """A group that fails (on whichever thread ran it) fails the chunk: the step that needs
    the chunk raises the error, and the env still closes (no thread left waiting)."""
    from navsim.sensors import imu as imu_mod

    venv = NavigationVectorEnv(N, "paper-2012", chunk_steps=20, score=False, threads=2, **OVER)
    venv.reset(seed=0)
    real = imu_mod.apply_imu_errors_batch_state

    def failing(*args, **kwargs):
        if args[7].size != IMU_GROUP:  # the second, smaller group
            raise FloatingPointError("injected")
        return real(*args, **kwargs)

    monkeypatch.setattr(imu_mod, "apply_imu_errors_batch_state", failing)
    with pytest.raises(FloatingPointError, match="injected"):
        for _ in range(20):
            venv.step(np.zeros((N, 9)))
    venv.close()
    assert venv._next is None and venv._loader is None
