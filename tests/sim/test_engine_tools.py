"""The engine's measuring tools (benchmarks/profile.py, benchmarks/compare.py) read what they claim."""

import importlib.util
import re
import subprocess
from pathlib import Path

import jax
import jax.numpy as jnp
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "benchmarks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _loop_hlo(n_fenced: int) -> str:
    """Optimised HLO of a loop whose body materialises ``n_fenced`` values behind conditionals
    (the engine's fences), each one kernel."""

    def body(_, c):
        xs, gate = c
        ys = [x * 1.5 + 0.25 for x in xs]
        return jax.lax.cond(gate, lambda v: v, lambda v: [a * 1 for a in v], ys), gate

    f = jax.jit(lambda xs, gate: jax.lax.fori_loop(0, 10, body, (xs, gate))[0])
    xs = [jnp.ones((64,), jnp.float32) for _ in range(n_fenced)]
    text = f.lower(xs, jnp.bool_(True)).compile().as_text()
    assert text is not None
    return text


def test_loop_body_cost_counts_the_kernels_of_the_loop():
    cost = _load("profile").loop_body_cost
    small, large = cost(_loop_hlo(2)), cost(_loop_hlo(6))
    assert small["fusions"] >= 2 and small["ops"] >= 2 * 2  # a multiply and an add per value
    assert large["fusions"] - small["fusions"] >= 4
    assert large["ops"] > small["ops"] and large["operands"] > small["operands"]
    assert cost("no loop here") == {"fusions": 0, "operands": 0, "ops": 0}


def test_compare_extracts_the_other_commits_package_under_another_name(tmp_path):
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout: no other commit to extract")
    compare = _load("compare")
    tree = compare.extract(head.stdout.strip(), tmp_path)
    pkg = tree / compare.ALIAS
    original = subprocess.run(["git", "-C", str(ROOT), "show", "HEAD:sanlab/sim/dynamics.py"], capture_output=True,
                              text=True, check=True).stdout
    copied = (pkg / "sim" / "dynamics.py").read_text()
    assert "from sanlab.sim import articulated" in original
    assert copied == original.replace("from sanlab.", f"from {compare.ALIAS}.")
    # nothing in the copy imports this tree's package
    for path in pkg.rglob("*.py"):
        assert not re.search(r"^\s*(from|import) sanlab\b", path.read_text(), re.M), path
