"""How fast live mode can run: ``python -m sanlab.studio.bench [--creature fish] [--seconds 20]``.

Makes a throw-away library with a tiny search on the creature, opens its best gait in a live
session (exactly what the studio's live mode runs, follow point held still) and steps it as fast
as it goes, as the server would without pacing. Prints the wall time per chunk, the
simulated-time/real-time ratio (above 1: faster than real time) and the frame rate it could
stream (frames of 1/60 s, i.e. every 17 steps of 1 ms). The studio itself paces to real time
(ratio about 1) and reports both numbers in the live view.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--creature", default="fish", help="built-in creature (default: fish)")
    ap.add_argument("--seconds", type=float, default=20.0, help="simulated seconds to step (default: 20)")
    ap.add_argument("--terrain", default=None, help="flat, slope, hill or rough (vertical-plane creatures)")
    a = ap.parse_args(argv)

    from sanlab.studio.service import Service

    with tempfile.TemporaryDirectory() as tmp:
        svc = Service(os.path.join(tmp, "bench.db"))
        prep = svc.prepare_search(creature=a.creature, controllers=16, seconds=0.5, seed=0)
        run_id = svc.search(prep["args"], lambda p: None)
        t0 = time.perf_counter()
        live = svc.live(f"{run_id}/1", a.terrain)
        live.step()  # compiles (once per creature and terrain kind)
        first = time.perf_counter() - t0
        n = max(1, int(round(a.seconds / live.chunk_seconds)))
        t0 = time.perf_counter()
        frames = 0
        for _ in range(n):
            frames += len(live.step()["t"])
        wall = time.perf_counter() - t0
    sim = n * live.chunk_seconds
    ratio = sim / wall
    print(f"{a.creature}: {n} chunks of {live.steps} steps ({live.chunk_seconds * 1000:.0f} ms, "
          f"{live.steps // live.every} frames) in {wall:.2f} s: {wall / n * 1000:.1f} ms per chunk; "
          f"first chunk (compile) {first:.1f} s")
    print(f"simulated/real time {ratio:.2f}; could stream {frames / wall:.0f} frames/s "
          f"(real time needs {1 / live.frame_dt:.1f})")


if __name__ == "__main__":
    main()
