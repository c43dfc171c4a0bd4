"""The layers of the package (docs in /work/shared/docs/style.md, "Layers"; issue 12): every
import of every module follows them, and no module imports itself back through others.

    cli, api -> app -> plot -> analysis -> data;   app -> schema -> physics;   analysis -> physics

A layer may import the layers below it (transitively); nothing imports ``app`` but ``cli``
and ``api``; ``data`` imports neither ``schema`` nor ``physics``. ``errors``,
``_version`` and ``_jaxconfig`` are the base every layer may import. Imports inside
functions count: a lazy import is still a dependency. The upstream-fix subclasses of
``physics/solver/upstream.py`` (diffrax, optimistix internals) are physics importing third-party
code, which these rules do not constrain.

No cycle is allowed. Inside ``physics`` the folders are layers too:

    physics.driver -> physics.solver -> the model (physics.*, bodies, static)

the solvers never import the driver, and the model (the sheet, its laws, the vector field, the
bodies, the static model) imports neither.
"""

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "dynslip"
BASE = {"errors", "_version", "_jaxconfig"}
# layer -> the layers it may import (itself and the base included)
ALLOWED = {
    "physics": {"physics"},
    "schema": {"schema", "physics"},
    "data": {"data"},
    "analysis": {"analysis", "data", "physics"},
    "plot": {"plot", "analysis", "data", "physics"},
    "app": {"app", "plot", "analysis", "data", "schema", "physics"},
    "api": {"api", "app", "plot", "analysis", "data", "schema", "physics"},
    "cli": {"cli", "app", "plot", "analysis", "data", "schema", "physics"},
    "__init__": {"api", "plot"},  # the package re-exports the API and the figures
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _imports(name: str, path: Path) -> set[str]:
    """The dynslip modules ``name`` imports (``from dynslip.x import y`` counts as
    ``dynslip.x.y`` when that is a module, else ``dynslip.x``)."""
    mods = _modules()
    is_pkg = path.name == "__init__.py"
    here = name if is_pkg else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here.split(".")[: len(here.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in mods else mod for a in node.names]
        else:
            continue
        for t in targets:
            if t == "dynslip" or t.startswith("dynslip."):
                while t not in mods and "." in t:
                    t = t.rpartition(".")[0]
                if t != name:
                    out.add(t)
    return out


def _layer(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def _graph() -> dict[str, set[str]]:
    return {name: _imports(name, path) for name, path in _modules().items()}


def test_every_import_follows_the_layers():
    bad = []
    for name, targets in _graph().items():
        layer = _layer(name)
        for t in targets:
            to = _layer(t)
            if to in BASE:
                continue
            if layer in BASE:
                bad.append(f"{name} -> {t} (the base imports no layer)")
            elif to not in ALLOWED[layer]:
                bad.append(f"{name} -> {t} ({layer} may import {sorted(ALLOWED[layer])})")
    assert not bad, "imports against the layers:\n" + "\n".join(sorted(bad))


#: physics' inner layers: each may import itself and those after it
PHYSICS_ROLES = ("driver", "solver", "model")


def _role(module: str) -> str:
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[2] in PHYSICS_ROLES[:-1] else "model"


def test_physics_folders_import_downward():
    bad = []
    for name, targets in _graph().items():
        if _layer(name) != "physics":
            continue
        mine = PHYSICS_ROLES.index(_role(name))
        for t in targets:
            if _layer(t) == "physics" and PHYSICS_ROLES.index(_role(t)) < mine:
                bad.append(f"{name} -> {t}")
    assert not bad, "physics folders imported upward:\n" + "\n".join(sorted(bad))


def test_physics_roles_are_read_from_the_folder():
    assert _role("dynslip.physics.solver.newton") == "solver"
    assert _role("dynslip.physics.driver") == "driver"
    assert _role("dynslip.physics.field") == _role("dynslip.physics.bodies.held") == "model"


def _cycles() -> list[list[str]]:
    graph = _graph()
    cycles, state = [], {}

    def visit(n, stack):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                cycles.append(" -> ".join(stack[stack.index(m):] + [m]))
            elif m not in state:
                visit(m, stack)
        stack.pop()
        state[n] = 2

    for n in sorted(graph):
        if n not in state:
            visit(n, [])
    return cycles


def test_no_import_cycle():
    found = _cycles()
    assert not found, "import cycles:\n" + "\n".join(found)


@pytest.mark.parametrize(("src", "dst", "ok"), [
    ("dynslip.plot.x", "dynslip.app.y", False), ("dynslip.data.x", "dynslip.schema.y", False),
    ("dynslip.data.x", "dynslip.physics.y", False), ("dynslip.schema.x", "dynslip.app.y", False),
    ("dynslip.analysis.x", "dynslip.plot.y", False), ("dynslip.app.x", "dynslip.physics.y", True),
    ("dynslip.cli", "dynslip.app.y", True), ("dynslip.physics.x", "dynslip.errors", True),
])
def test_the_rules_themselves(src, dst, ok):
    """The table above says what the issue says (a check of the checker)."""
    to = _layer(dst)
    assert (to in BASE or to in ALLOWED[_layer(src)]) == ok


# --- one concept per room (issue 24) ------------------------------------------------------

#: what an app module may not import: models are the schema's (pydantic), datasets and their
#: algorithms are data's and analysis's (xarray). A module's length is not checked: ruff's
#: complexity rules are (C901, PLR0913; pyproject.toml, tests/test_style.py; issue 43).
APP_FORBIDDEN = ("pydantic", "xarray")


def _third_party(path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module.split(".")[0])
    return out


def test_app_defines_no_model_and_no_dataset_algorithm():
    """``app/`` only orchestrates: no module there imports pydantic (so defines no model) or
    xarray (so builds no dataset and runs no algorithm over one), and no class there derives
    from a pydantic model of the schema."""
    bad = []
    for name, path in _modules().items():
        if _layer(name) != "app":
            continue
        for lib in sorted(_third_party(path) & set(APP_FORBIDDEN)):
            bad.append(f"{name} imports {lib}")
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ClassDef):
                bases = {ast.unparse(b).split(".")[-1] for b in node.bases}
                models = {"BaseModel", "_Strict", "_Model"}
                if bases & models or any(b.endswith("Spec") for b in bases):
                    bad.append(f"{name}.{node.name} is a model")
    assert not bad, "app/ does more than orchestrate:\n" + "\n".join(bad)


def test_the_room_checks_find_what_they_look_for(tmp_path):
    """A check of the checker: a pydantic import and an xarray import are found."""
    f = tmp_path / "m.py"
    f.write_text('"""x"""\nfrom pydantic import BaseModel\nimport xarray as xr\n')
    assert _third_party(f) & set(APP_FORBIDDEN) == {"pydantic", "xarray"}
