"""Global JAX settings change only through ``sanlab.configure()``, never on import."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from tests.helpers import ROOT

PROBE = """
import json, os, sys
{before}
import jax
print(json.dumps({{"x64": bool(jax.config.jax_enable_x64), "xla_flags": os.environ.get("XLA_FLAGS")}}))
"""


def _probe(before: str) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAX_ENABLE_X64")}
    env["PYTHONPATH"] = str(ROOT)
    env["SANLAB_NO_COMPILE_CACHE"] = "1"
    r = subprocess.run([sys.executable, "-c", PROBE.format(before=before)], capture_output=True,
                       text=True, env=env, timeout=120, check=True)
    return json.loads(r.stdout.splitlines()[-1])


def test_importing_the_simulator_leaves_jax_settings_alone():
    seen = _probe("import sanlab, sanlab.sim, sanlab.san, sanlab.metrics, sanlab.evaluate")
    assert seen == {"x64": False, "xla_flags": None}


def test_configure_splits_the_host_and_enables_float64():
    seen = _probe("import sanlab; sanlab.configure(); sanlab.configure()")
    assert seen["x64"] is True
    assert "--xla_force_host_platform_device_count=" in seen["xla_flags"]
