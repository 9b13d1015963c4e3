"""sanlab needs no JAX: the simulator is its own compiled kernel since issue 46.

JAX (with jaxlib, about 380 MB installed) may still be in the environment for other reasons; no
module of sanlab may import it, nor what only JAX needed, and the package does not ask for it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib

from tests.helpers import ROOT

GONE = ("jax", "jaxlib", "flatbuffers", "ml_dtypes", "opt_einsum")

PROBE = """
import importlib, pkgutil, sys, tempfile, os
import sanlab
for m in pkgutil.walk_packages(sanlab.__path__, "sanlab."):
    if m.name.endswith("__main__") or m.name.endswith("_kernel_lib"):
        continue
    importlib.import_module(m.name)
from typer.testing import CliRunner
from sanlab.cli import app
with tempfile.TemporaryDirectory() as tmp:
    db = os.path.join(tmp, "g.db")
    for args in (["search", "cart", "-n", "8", "--seconds", "0.3", "--db", db], ["check", "bounder", "--simulate"],
                 ["simulate", "fish", "-n", "4", "--seconds", "0.2"]):
        r = CliRunner().invoke(app, args)
        assert r.exit_code == 0, (args, r.output)
print(sorted({k.split(".")[0] for k in sys.modules}))
"""


def test_no_module_of_sanlab_imports_jax_nor_a_search_does():
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    loaded = set(eval(r.stdout.strip().splitlines()[-1]))
    assert "sanlab" in loaded and not loaded & set(GONE), sorted(loaded & set(GONE))


def test_the_package_does_not_depend_on_jax():
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    wanted = list(project["dependencies"]) + [d for ds in project["optional-dependencies"].values() for d in ds]
    names = {d.split(";")[0].split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip().lower() for d in wanted}
    assert not names & set(GONE), sorted(names & set(GONE))


# -- issue 57 item 14: pyribs (numba, llvmlite, pandas: about 300 MB) is the optional qd extra ------


def test_pyribs_is_the_qd_extra_and_the_tests_install_it():
    with open(ROOT / "pyproject.toml", "rb") as f:
        project = tomllib.load(f)["project"]
    name = lambda d: d.split(";")[0].split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip().lower()
    assert "ribs" not in {name(d) for d in project["dependencies"]}
    assert [name(d) for d in project["optional-dependencies"]["qd"]] == ["ribs"]
    assert "sanlab[qd]" in project["optional-dependencies"]["test"]


def _without_ribs(monkeypatch):
    import sys as _sys

    for k in [k for k in _sys.modules if k == "ribs" or k.startswith("ribs.")]:
        monkeypatch.delitem(_sys.modules, k)
    monkeypatch.setitem(_sys.modules, "ribs", None)  # `import ribs...` now raises ImportError


def test_map_elites_and_design_without_pyribs_say_which_extra_to_install(monkeypatch, tmp_path):
    import pytest
    from typer.testing import CliRunner

    from sanlab.cli import app
    from sanlab.search.map_elites import MissingExtra, ribs

    _without_ribs(monkeypatch)
    with pytest.raises(MissingExtra, match=r"^--strategy map-elites needs pyribs, which is not installed: pip install 'sanlab\[qd\]'$"):
        ribs("archives", "--strategy map-elites")
    db = str(tmp_path / "l.db")
    r = CliRunner().invoke(app, ["search", "cart", "--strategy", "map-elites", "-n", "8", "--db", db])
    assert r.exit_code == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r.output
    assert r.stderr == "search: --strategy map-elites needs pyribs, which is not installed: pip install 'sanlab[qd]'\n"
    r = CliRunner().invoke(app, ["design", str(ROOT / "tests" / "data" / "hopper_free.toml"), "--db", db])
    assert r.exit_code == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r.output
    assert r.stderr.startswith("design: --strategy cma-es needs pyribs") and "pip install 'sanlab[qd]' (or --strategy random)" in r.stderr
    r = CliRunner().invoke(app, ["search", "cart", "-n", "8", "--seconds", "0.3", "--db", db, "--json"])
    assert r.exit_code == 0, r.output  # random search needs no pyribs
