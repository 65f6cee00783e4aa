"""The house's architecture as an invariant: imports point down the layers, nothing imports a
CLI, and no two modules import each other (directly or in a cycle), lazy imports included.

Layers, lowest first: ``infra`` (run infrastructure) → ``evolve`` (the learning, pure
numerics) and ``servo_mj.robot`` (the robot in MuJoCo) → ``servo_mj.world`` (the world it
walks in) → ``calibration`` → ``servobot`` (the applications) → ``servobot.cli``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("infra", "evolve", "servo_mj", "calibration", "servobot")

LAYER_DEPS: dict[str, set[str]] = {
    "infra": set(),
    "evolve": {"infra"},
    "servo_mj": set(),
    "servo_mj.robot": {"infra"},
    "servo_mj.world": {"infra", "evolve", "servo_mj.robot"},
    "calibration": {"infra", "evolve", "servo_mj.robot", "servo_mj.world"},
    "servobot": {"infra", "evolve", "servo_mj.robot", "servo_mj.world", "calibration"},
    "servobot.cli": {
        "infra", "evolve", "servo_mj.robot", "servo_mj.world", "calibration", "servobot",
    },
}  # fmt: skip
"""What each layer may import besides itself."""


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _layer(module: str) -> str:
    """The most specific layer that ``module`` belongs to."""
    if module == "servobot.__main__":  # ``python -m servobot``: the command line
        return "servobot.cli"
    best = ""
    for layer in LAYER_DEPS:
        if (module == layer or module.startswith(layer + ".")) and len(layer) > len(best):
            best = layer
    return best


def _imports(path: Path, modules: set[str]) -> set[str]:
    """Every module ``path`` imports, at any depth of the file (lazy ones too); for
    ``from pkg import name`` that is ``pkg.name`` when it is a project module, else ``pkg``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                found.add(sub if sub in modules else node.module)
    return found


FILES = {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def _graph() -> dict[str, set[str]]:
    modules = set(FILES)
    return {
        mod: {d for d in _imports(path, modules) if d in modules and d != mod}
        for mod, path in FILES.items()
    }


GRAPH = _graph()


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_imports_point_down_the_layers(module: str) -> None:
    layer = _layer(module)
    allowed = LAYER_DEPS[layer] | {layer}
    for dep in GRAPH[module]:
        dep_layer = _layer(dep)
        if dep == "servo_mj" or dep_layer == layer:  # a package's own __init__, same layer
            continue
        assert dep_layer in allowed, f"{module} ({layer}) imports {dep} ({dep_layer})"


def test_no_module_outside_the_cli_imports_a_cli_module() -> None:
    for module, deps in GRAPH.items():
        if _layer(module) == "servobot.cli":
            continue
        assert not any(_layer(d) == "servobot.cli" for d in deps), module


@pytest.mark.parametrize("layer", ["infra", "evolve"])
def test_pure_layers_never_import_mujoco_code(layer: str) -> None:
    """The table simulation installs and runs without physics or recording (even lazily)."""
    for mod, path in FILES.items():
        if _layer(mod) != layer:
            continue
        tops = {n.split(".")[0] for n in _imports(path, set(FILES))}
        assert not tops & {"mujoco", "dm_control", "rerun", "servo_mj"}, mod


def test_no_import_cycles() -> None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(GRAPH[m]):
            if state.get(d) == 1:
                cycle = stack[stack.index(d) :] + [d]
                raise AssertionError("import cycle: " + " → ".join(cycle))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(GRAPH):
        if m not in state:
            visit(m)


def test_the_layer_check_sees_a_violation() -> None:
    """The checker itself: an upward import is found (guards against a vacuous pass)."""
    assert _layer("evolve.kernel") == "evolve"
    assert _layer("servobot.cli.validate") == "servobot.cli"
    assert "servo_mj.robot" not in LAYER_DEPS["evolve"]
    assert "servo_mj.world.physics_world" in GRAPH["servobot.validation.lone"]
