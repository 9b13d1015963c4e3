"""The package's layers: no import runs back up, and no module imports itself round a cycle.

Layers, lowest first (a module may import from its own layer and the ones below):

    base              sanlab (the package: __version__)
    creature          the spec and the file format
    sim               compile, step, roll out
    san, metrics      controllers and observers of a rollout (metrics, descriptors); interop (MJCF export) sits here too,
                      above sim, which it may use
    evaluate          evaluate (scoring batches), gait (a stored controller with its creature,
                      replayed), random_sans (random SANs summarised, `sanlab simulate`),
                      tuned (a gait in the creature file's terms), check (a creature dropped
                      for a second: `sanlab check --simulate`)
    library           the gait library (SQLite)
    search | render   side by side, neither imports the other: search holds the phase 1 and 2
                      drivers, reproduce (both phases per creature, the Table 1 report), design
                      (free numbers searched with robust tuned speed) and
                      audit (a gait re-scored under nudges), modes (a run's gaits grouped);
                      render draws scenes, scores and traces it is handed
    cli, studio, gym  the applications: the command line, the web studio, and Gymnasium
                      environments (sanlab.gym)

Every import counts, including those inside functions and under TYPE_CHECKING: a lazy import is
still a dependency. Every module of the package must belong to a layer, so a new top-level
module is placed here on purpose.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "sanlab"

# (layer, {group: module prefixes}), lowest first; a layer of several groups keeps them apart
# only where SIDE_BY_SIDE says so.
LAYERS: list[tuple[str, dict[str, tuple[str, ...]]]] = [
    ("base", {"base": ("sanlab",)}),
    ("creature", {"creature": ("sanlab.creature",)}),
    ("sim", {"sim": ("sanlab.sim",)}),
    ("san and metrics", {"san": ("sanlab.san",), "metrics": ("sanlab.metrics", "sanlab.descriptors"), "interop": ("sanlab.interop",)}),
    ("evaluate", {"evaluate": ("sanlab.evaluate", "sanlab.gait", "sanlab.random_sans", "sanlab.tuned", "sanlab.check")}),
    ("library", {"library": ("sanlab.library",)}),
    ("search and render", {"search": ("sanlab.search", "sanlab.reproduce", "sanlab.design", "sanlab.audit", "sanlab.modes"), "render": ("sanlab.render",)}),
    ("cli and studio", {"cli": ("sanlab.cli", "sanlab.__main__"), "studio": ("sanlab.studio",), "gym": ("sanlab.gym",)}),
]
SIDE_BY_SIDE = {"search and render"}
EXACT = {"sanlab"}  # the package itself, not everything under it


def modules(root: Path = PACKAGE) -> dict[str, Path]:
    """Dotted name -> file of every module under ``root`` (a package's __init__ is the package)."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The sanlab modules that module ``name`` (file ``path``) imports, anywhere in it."""
    is_package = path.name == "__init__.py"
    package = name if is_package else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for a in node.names:  # `from sanlab import sim` imports the module sanlab.sim
                sub = f"{target}.{a.name}"
                found.add(sub if sub in known else target)
    return {m for m in found if m == "sanlab" or m.startswith("sanlab.")}


def graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    mods = modules(root)
    known = set(mods)
    return {name: imports(name, path, known) - {name} for name, path in mods.items()}


def place(module: str) -> tuple[int, str, str]:
    """(rank, layer, group) of ``module``: the longest matching prefix wins."""
    best = None
    for rank, (layer, groups) in enumerate(LAYERS):
        for group, prefixes in groups.items():
            for p in prefixes:
                hit = module == p or (p not in EXACT and module.startswith(p + "."))
                if hit and (best is None or len(p) > best[0]):
                    best = (len(p), rank, layer, group)
    if best is None:
        raise LookupError(f"{module} is in no layer: place it in tests/test_layers.py")
    return best[1:]


def violations(g: dict[str, set[str]]) -> list[str]:
    """Every import that runs up the layers, or sideways between side-by-side groups."""
    out = []
    for a, targets in sorted(g.items()):
        ra, la, ga = place(a)
        for b in sorted(targets):
            rb, lb, gb = place(b)
            if rb > ra:
                out.append(f"{a} ({la}) imports {b} ({lb}), a higher layer")
            elif rb == ra and ga != gb and la in SIDE_BY_SIDE:
                out.append(f"{a} ({ga}) imports {b} ({gb}): side by side, they stay apart")
    return out


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of ``g`` (one per strongly connected component of several modules)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_every_module_is_in_a_layer():
    unplaced = []
    for m in modules():
        try:
            place(m)
        except LookupError as e:
            unplaced.append(str(e))
    assert not unplaced, "\n".join(unplaced)


def test_no_import_runs_up_the_layers():
    assert violations(graph()) == []


def test_no_import_cycles():
    assert cycles(graph()) == []


# module -> the only package that may import it: the kernel's calls and the parts they are split into
PRIVATE = {"sanlab.sim.kernel": "sanlab.sim", "sanlab.sim.native": "sanlab.sim", "sanlab.sim.tables": "sanlab.sim",
           "sanlab.sim.layout": "sanlab.sim"}


def private_imports(g: dict[str, set[str]]) -> list[str]:
    """Every import of a module of :data:`PRIVATE` from outside the package that owns it."""
    return [f"{a} imports {b}, which only {owner} may: use {owner}'s API"
            for a, targets in sorted(g.items()) for b in sorted(targets)
            if (owner := PRIVATE.get(b)) and not (a == owner or a.startswith(owner + "."))]


def test_nothing_outside_sim_imports_its_kernel():
    # the kernel's tables and calls change with it; the layers above use sim's API (sim.Rows,
    # sim.Observe, sim.poses(..., params_batched=True), ...), so it can change alone
    assert private_imports(graph()) == []


def test_the_private_check_catches_a_kernel_import():
    g = {k: set(v) for k, v in graph().items()}
    assert "sanlab.sim.kernel" in g["sanlab.sim.rollout"]  # inside sim: allowed, and seen
    g["sanlab.gym._core"].add("sanlab.sim.kernel")
    assert private_imports(g) == [
        "sanlab.gym._core imports sanlab.sim.kernel, which only sanlab.sim may: use sanlab.sim's API"]
    mods = modules()
    src = "from sanlab.sim import kernel\n"
    assert "sanlab.sim.kernel" in _imports_of_text(src, set(mods))  # the form gym and search used


def _imports_of_text(text: str, known: set[str]) -> set[str]:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "probe.py"
        path.write_text(text)
        return imports("sanlab.gym.probe", path, known)


def test_render_takes_data_not_a_library_or_a_command_line():
    # render sits above the library in the layers, but reads none: the cli hands it scenes,
    # scores and traces (so it works from a notebook without SQLite or Typer).
    mods = modules()
    for name, path in mods.items():
        if name == "sanlab.render" or name.startswith("sanlab.render."):
            deps = imports(name, path, set(mods)) | _third_party(path)
            assert not {d for d in deps if d.split(".")[0] in ("typer", "rich", "sqlite3")}, name
            assert not {d for d in deps if d.startswith(("sanlab.library", "sanlab.cli"))}, name


def _third_party(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module)
    return out


def test_the_checks_catch_an_upward_arrow_a_sideways_one_and_a_cycle():
    g = graph()
    assert "sanlab.library" in g["sanlab.search.runner"]  # the walk sees real imports
    assert "sanlab.sim.model" in g["sanlab.search.space"]
    assert "sanlab.creature.spec" in g["sanlab.creature.loader"]  # relative ones too
    bad = {k: set(v) for k, v in g.items()}
    bad["sanlab.sim.rollout"].add("sanlab.library.store")  # up
    bad["sanlab.render.scene"].add("sanlab.search.space")  # sideways
    assert violations(bad) == [
        "sanlab.render.scene (render) imports sanlab.search.space (search): side by side, they stay apart",
        "sanlab.sim.rollout (sim) imports sanlab.library.store (library), a higher layer",
    ]
    loop = {k: set(v) for k, v in g.items()}
    loop["sanlab.creature.spec"].add("sanlab.creature.files")  # files -> loader -> spec -> files
    assert any({"sanlab.creature.spec", "sanlab.creature.files"} <= set(c) for c in cycles(loop))
    with pytest.raises(LookupError, match=r"sanlab\.newthing"):
        place("sanlab.newthing")
    assert place("sanlab.studio.server")[1] == "cli and studio"
