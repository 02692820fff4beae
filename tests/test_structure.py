"""The package's layers: every import of one part of mechsim by another (at the top of a
module or inside a function) points down the table below, the architecture that
docs/architecture.md describes. A part is a subpackage or a module directly under mechsim."""

import ast
import pathlib

import mechsim

ROOT = pathlib.Path(mechsim.__file__).parent

# Bottom first. A part may import the parts of the layers below its own, never its own
# layer's other parts nor a layer above.
LAYERS = [
    {"records", "tolerances", "files", "options", "progress", "threads", "linalg",
     "integrators", "fem",
     "kinematics"},
    {"codegen"},
    {"flexible"},
    {"model"},
    {"symbolic", "problem", "study", "objectives"},
    {"assembly", "formulations", "results", "design"},
    {"build", "run", "linear"},
    {"engineering"},
    {"shooting"},
    {"facade"},
    {"examples"},
    {"app"},
]
LEVEL = {part: k for k, layer in enumerate(LAYERS) for part in layer}


def part_of(path: pathlib.Path) -> str:
    rel = path.relative_to(ROOT).parts
    return rel[0][:-3] if len(rel) == 1 else rel[0]


def imported_parts(path: pathlib.Path, source: str | None = None):
    """(line, part) of every mechsim part the module at `path` (its text `source`, default
    the file's) imports."""
    package = list(path.relative_to(ROOT).parts[:-1])
    for node in ast.walk(ast.parse(path.read_text() if source is None else source)):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                if (node.module or "").startswith("mechsim."):
                    yield node.lineno, node.module.split(".")[1]
                continue
            base = package[: len(package) - (node.level - 1)]
            target = base + (node.module.split(".") if node.module else [])
            if target:
                yield node.lineno, target[0]
            else:                                   # from . import x, y (the package root)
                for alias in node.names:
                    yield node.lineno, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("mechsim."):
                    yield node.lineno, alias.name.split(".")[1]


def modules():
    return [p for p in sorted(ROOT.rglob("*.py"))
            if part_of(p) not in ("__init__", "__main__")]


def test_every_part_has_a_layer():
    parts = {part_of(p) for p in modules()}
    assert parts <= set(LEVEL), f"parts without a layer: {sorted(parts - set(LEVEL))}"
    assert set(LEVEL) <= parts, f"layers name parts that do not exist: {sorted(set(LEVEL) - parts)}"


def test_imports_point_down():
    upward = []
    for path in modules():
        own = part_of(path)
        for line, target in imported_parts(path):
            if target == own or target not in LEVEL:
                continue
            if LEVEL[target] >= LEVEL[own]:
                upward.append(f"{path.relative_to(ROOT)}:{line} {own} -> {target}")
    assert not upward, "imports that do not point down:\n" + "\n".join(upward)


def test_the_check_sees_an_upward_import(tmp_path):
    """The parser reads relative imports at every depth and inside functions (a check that
    cannot see an arrow up would pass anything)."""
    fake = ROOT / "model" / "fake.py"
    source = "def f():\n    from ..run.solver import simulate\n    from .. import app\n"
    found = [t for _, t in imported_parts(fake, source)]
    assert found == ["run", "app"]


def test_the_algorithms_reach_compiled_code_through_the_algebra_only():
    """The formulations, the monitor, the run and the analyses are written once against
    the constraint algebra (`mechsim.problem.algebra`): none of them imports the code
    generation (the compiled engine serves them as the dense algebra's implementation)."""
    direct = [f"{path.relative_to(ROOT)}:{line}" for path in modules()
              if part_of(path) in ("formulations", "run", "engineering", "shooting", "linear")
              for line, target in imported_parts(path) if target == "codegen"]
    assert not direct, "algorithms that import codegen:\n" + "\n".join(direct)
