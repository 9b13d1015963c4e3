"""Live mode's continuation (``service._continuation``) against ``sim.rollout``: the studio runs
the simulator's loop itself, one creature per call, to save rollout's per-call batching; these
tests fail if the two stop agreeing (a change in the rollout's loop the studio has not followed),
or if live mode starts compiling per chunk instead of once per creature."""

from __future__ import annotations

import numpy as np
import pytest

from sanlab import sim
from sanlab.render.scene import poses
from sanlab.studio.service import LIVE_CHUNK, LIVE_FPS, Service, StudioError, _continuation

CHUNKS = 3


def gait_id(library, which: str) -> str:
    return f"{library['cart']}/1" if which == "cart" else str(library["fish"])


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
@pytest.mark.parametrize("which", ["cart", "fish"])
def test_live_chunks_continue_the_run_as_one_rollout_would(library, which):
    """CHUNKS live chunks, each continuing from the state the last one left, give the frames of
    one uninterrupted ``sim.rollout`` of the same controller on the same model (the fish with its
    follow point held still, off to its left, as live mode holds it): the same step, no second
    physics (to float rounding, see below)."""
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
    bits = np.asarray(r.frames.bits[0]) > 0.5
    nodes = np.asarray(r.frames.cstate.out[0]) > 0.5
    # The first chunk agrees to the page's 5 digits, sensor by sensor and node by node. After it
    # the two programs (compiled apart: one creature here, a sharded batch there) differ in the
    # last bits, and a contact's stick-or-slip decision can amplify that: the whole run agrees
    # to a millimetre.
    first = slice(0, LIVE_CHUNK)
    np.testing.assert_allclose(links[first], P["links"][first], rtol=0, atol=2e-5)
    np.testing.assert_allclose(com[first], P["com"][first], rtol=0, atol=2e-5)
    assert np.array_equal(np.asarray(chunks[0]["bits"]), bits[first])
    assert np.array_equal(np.asarray(chunks[0]["nodes"]), nodes[first])
    np.testing.assert_allclose(links, P["links"], rtol=0, atol=1e-3)
    np.testing.assert_allclose(com, P["com"], rtol=0, atol=1e-3)
    np.testing.assert_allclose(np.concatenate([c["t"] for c in chunks]), r.frames.t, atol=1e-9)
    # the run moves (a still creature would match any rollout)
    assert np.abs(links[-1] - links[0]).max() > 1e-3
    if which == "fish":
        assert bits[0, 0] and not bits[0, 1]  # at first its left eye sees the point, its right one not
        assert all(c["follow"] == [0.3, 0.3] for c in chunks)
    # the carried state is the rollout's final state, to that precision
    np.testing.assert_allclose(np.asarray(live.state.q), np.asarray(r.state.q[0]), rtol=0, atol=1e-3)
    assert live.t == float(np.asarray(r.state.t)[0])


@pytest.mark.slow  # over 4 s even with a warm compile cache (the pre-commit subset leaves it out)
def test_the_continuation_compiles_once_per_creature_not_per_chunk(library):
    """The first chunk of a creature may compile; later chunks, a second session of the same gait
    (even through another Service), moving the follow point and a reset do not; a new terrain
    kind compiles once, and going back to one already seen does not."""
    run = _continuation()
    if not hasattr(run, "_cache_size"):
        pytest.skip("this jax has no _cache_size on jitted functions")
    fish = gait_id(library, "fish")
    live = Service(library["db"]).live(fish)
    live.step()
    n = run._cache_size()
    live.step()
    live.set_follow(0.4, -0.2)
    live.step()
    live.reset()
    live.step()
    again = Service(library["db"]).live(fish)
    again.step()
    again.step()
    assert run._cache_size() == n

    cart = Service(library["db"]).live(gait_id(library, "cart"))
    cart.step()
    n = run._cache_size()
    cart.set_terrain("slope")
    cart.step()
    assert run._cache_size() <= n + 1
    n = run._cache_size()
    cart.step()
    cart.set_terrain(None)
    cart.step()
    cart.set_terrain("slope")
    cart.step()
    assert run._cache_size() == n


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
