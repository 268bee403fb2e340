"""The package's shape: no import circles between its modules (imports inside functions
count: a circle closed lazily is still a circle), the library (`import echogym`) loads
no application and none of the optional stacks (matplotlib, torch, torchrl, SB3), and
every third-party module the package imports is declared in pyproject.toml: the
library's in the core dependencies, the rest in an extra."""

from __future__ import annotations

import ast
import importlib.metadata
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "python" / "echogym"
#: Subpackages that are applications, not library.
APPLICATIONS = ("echogym.apps", "echogym.train")
#: The console script, which dispatches to the applications.
COMMAND_LINE = ("echogym.cli", "echogym.__main__")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path, modules: set[str] = frozenset()) -> set[str]:
    """Absolute names of every module ``path`` imports, anywhere in its body. ``from P
    import m`` of a submodule ``P.m`` (one of ``modules``) imports ``P.m``; the package
    ``P`` itself is then only the parent every submodule import initialises first."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.add(sub if sub in modules else base)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: {m for m in _imports(name, path, set(modules)) if m in modules and m != name}
            for name, path in modules.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (a path that returns to its start), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (found := visit(start)):
            return found
    return None


def test_the_cycle_finder_finds_circles():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_sees_lazy_and_package_imports():
    graph = _graph()
    assert "echogym.gym_env" in graph["echogym"]
    assert "echogym.spaces" in graph["echogym.gym_env"]  # `from echogym import spaces`
    assert "echogym.train.scale_out" in graph["echogym.train.ppo"]  # inside a method


def test_no_import_circles():
    cycle = _cycle(_graph())
    assert cycle is None, "import circle: " + " → ".join(cycle or [])


def test_the_library_imports_no_application():
    for name, targets in _graph().items():
        if name.startswith(APPLICATIONS + COMMAND_LINE):
            continue
        apps = sorted(t for t in targets if t.startswith(APPLICATIONS))
        assert not apps, f"{name} (library) imports {apps}"


def test_library_modules_never_import_matplotlib():
    for name, path in _modules().items():
        if name.startswith(APPLICATIONS + COMMAND_LINE):
            continue
        bad = sorted(m for m in _imports(name, path) if m.split(".")[0] == "matplotlib")
        assert not bad, f"{name} imports {bad}"


def test_import_echogym_loads_no_optional_stack():
    probe = ("import sys, echogym; print(__import__('json').dumps(sorted(m for m in sys.modules "
             "if m.split('.')[0] in ('matplotlib', 'torch', 'torchrl', 'tensordict', "
             "'stable_baselines3', 'ray', 'tqdm', 'PIL', 'rerun', 'moviepy') or "
             "m.startswith(('echogym.apps', "
             "'echogym.train')))))")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=120, check=True)
    assert json.loads(done.stdout) == []


def _requirement_name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def _declared() -> tuple[set[str], set[str]]:
    """Distribution names in the core dependencies, and in any extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {_requirement_name(r) for r in project["dependencies"]}
    extras = {_requirement_name(r) for rs in project["optional-dependencies"].values() for r in rs}
    return core, extras - {"echogym"}


#: Distributions whose modules are named otherwise, for when they are not installed.
MODULE_DISTRIBUTIONS = {"PIL": "pillow", "stable_baselines3": "stable-baselines3"}


def _distributions(names: set[str]) -> set[str]:
    """The distributions providing the top-level modules ``names`` (besides the standard
    library and echogym): the installed ones, else by name."""
    providers = importlib.metadata.packages_distributions()
    out = set()
    for top in names - set(sys.stdlib_module_names) - {"echogym", "__future__"}:
        found = providers.get(top) or [MODULE_DISTRIBUTIONS.get(top, top)]
        out.update(d.lower().replace("_", "-") for d in found)
    return out


def test_every_third_party_import_is_declared():
    core, extras = _declared()
    library: set[str] = set()
    everything: set[str] = set()
    # Adapters that need an extra are library modules imported on their own; so is the
    # robot-data subpackage (`echogym[robotdata]`: rosbags, pyarrow).
    optional_adapters = ("echogym.torchrl", "echogym.sb3", "echogym.rerun_log",
                         "echogym.video", "echogym.robotdata")
    for name, path in _modules().items():
        tops = {m.split(".")[0] for m in _imports(name, path)}
        everything |= tops
        if not name.startswith(APPLICATIONS + COMMAND_LINE + optional_adapters):
            library |= tops
    undeclared_library = _distributions(library) - core
    assert not undeclared_library, f"the library imports {undeclared_library}, not core dependencies"
    undeclared = _distributions(everything) - core - extras
    assert not undeclared, f"imported but not declared in pyproject.toml: {undeclared}"
