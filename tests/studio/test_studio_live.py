"""Live mode against ``sim.rollout``: a live run is chunks of the rollout, each continuing from the
state the last one left (``state0=``, ``cstate0=``), so the chunks together are one uninterrupted
rollout, bit for bit (the page gets 5 digits)."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import sim
from sanlab.render.scene import poses
from sanlab.studio.service import LIVE_CHUNK, LIVE_FPS, Service, StudioError

CHUNKS = 3


def gait_id(library, which: str) -> str:
    return f"{library['cart']}/1" if which == "cart" else str(library["fish"])


@pytest.mark.parametrize("which", ["cart", "fish"])
def test_live_chunks_continue_the_run_as_one_rollout_would(library, which):
    """CHUNKS live chunks give the frames of one uninterrupted ``sim.rollout`` of the same
    controller on the same model (the fish with its follow point held still, off to its left, as
    live mode holds it): the same kernel, no second physics."""
    live = Service(library["db"]).live(gait_id(library, which))
    if which == "fish":
        live.set_follow(0.3, 0.3)  # straight ahead, where it starts, neither eye sees it
    chunks = [live.step() for _ in range(CHUNKS)]
    assert all(c["finite"] for c in chunks)
    gait = live.gait
    model = live._stepped_model()
    r = sim.rollout(model, gait.san, gait.san_params(), steps=CHUNKS * live.steps, record_fps=LIVE_FPS)
    assert r.frames is not None
    q = np.asarray(r.frames.q[0])
    assert q.shape[0] == CHUNKS * LIVE_CHUNK
    P = poses(model, q)
    links = np.concatenate([np.asarray(c["links"]) for c in chunks])
    com = np.concatenate([c["com"] for c in chunks])
    np.testing.assert_allclose(links, P["links"], rtol=0, atol=1e-5)  # the page's 5 digits
    np.testing.assert_allclose(com, P["com"], rtol=0, atol=1e-5)
    bits = np.concatenate([np.asarray(c["bits"]) for c in chunks])
    nodes = np.concatenate([np.asarray(c["nodes"]) for c in chunks])
    assert np.array_equal(bits, np.asarray(r.frames.bits[0]) > 0.5)
    assert np.array_equal(nodes, np.asarray(r.frames.cstate.out[0]) > 0.5)
    np.testing.assert_allclose(np.concatenate([c["t"] for c in chunks]), r.frames.t, atol=1e-9)
    # the run moves (a still creature would match any rollout)
    assert np.abs(links[-1] - links[0]).max() > 1e-3
    if which == "fish":
        assert bits[0, 0] and not bits[0, 1]  # at first its left eye sees the point, its right one not
        assert all(c["follow"] == [0.3, 0.3] for c in chunks)
    # the carried state is the rollout's final state, bit for bit
    assert np.array_equal(np.asarray(live.state.q), np.asarray(r.state.q))
    assert live.t == float(np.asarray(r.state.t)[0])


def test_a_reset_starts_again_from_rest(library):
    live = Service(library["db"]).live(f"{library['cart']}/1")
    first = live.step()
    live.step()
    live.reset()
    again = live.step()
    assert again["t"] == first["t"] and again["links"] == first["links"]


def test_a_bad_terrain_changes_nothing(library):
    live = Service(library["db"]).live(f"{library['cart']}/1")
    live.step()
    state, t, model = live.state, live.t, live.model
    with pytest.raises(StudioError, match="terrain: expected one of"):
        live.check_terrain("lava")
    with pytest.raises(StudioError, match="terrain: expected one of"):
        live.set_terrain("lava")
    assert (live.state, live.t, live.model, live.terrain) == (state, t, model, None)
    fish = Service(library["db"]).live(str(library["fish"]))
    with pytest.raises(StudioError, match="horizontal plane"):
        fish.check_terrain("flat")
    fish.check_terrain(None)  # its own ground: fine
