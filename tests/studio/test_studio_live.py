"""Live mode's continuation (``service._continuation``) against ``sim.rollout``: the studio runs
the simulator's loop itself, one creature per call, to save rollout's per-call batching; these
tests fail if the two stop agreeing (a change in the rollout's loop the studio has not followed)."""

from __future__ import annotations

import numpy as np

from sanlab import sim
from sanlab.render.scene import poses
from sanlab.studio.service import LIVE_CHUNK, LIVE_FPS, Service


def test_live_chunks_continue_the_run_as_one_rollout_would(library):
    live = Service(library["db"]).live(f"{library['cart']}/1")
    chunks = [live.step() for _ in range(2)]
    assert all(c["finite"] for c in chunks)
    gait = live.gait
    r = sim.rollout(live.model, gait.san, gait.san_params(), steps=2 * live.steps, record_fps=LIVE_FPS)
    assert r.frames is not None
    q = np.asarray(r.frames.q[0])
    assert q.shape[0] == 2 * LIVE_CHUNK
    P = poses(live.model, q)
    links = np.concatenate([np.asarray(c["links"]) for c in chunks])
    np.testing.assert_allclose(links, P["links"], rtol=0, atol=2e-5)  # the page's 5 digits
    assert np.array_equal(np.concatenate([c["bits"] for c in chunks]), np.asarray(r.frames.bits[0]) > 0.5)
    assert np.array_equal(np.concatenate([c["nodes"] for c in chunks]), np.asarray(r.frames.cstate.out[0]) > 0.5)
    np.testing.assert_allclose(np.concatenate([c["t"] for c in chunks]), r.frames.t, atol=1e-9)
    # the carried state is the rollout's final state, to float32 rounding: the two programs are
    # compiled apart (one creature here, a padded batch there), so the last bits may differ
    np.testing.assert_allclose(np.asarray(live.state.q), np.asarray(r.state.q[0]), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(np.asarray(live.state.p), np.asarray(r.state.p[0]), rtol=1e-4, atol=1e-5)
    assert live.t == float(np.asarray(r.state.t)[0])


def test_a_reset_starts_again_from_rest(library):
    live = Service(library["db"]).live(f"{library['cart']}/1")
    first = live.step()
    live.step()
    live.reset()
    again = live.step()
    assert again["t"] == first["t"] and again["links"] == first["links"]
