"""The packages' layers, read from their sources (every import statement, at module level
or inside a function): dfa_model (the model and the `dfa` core) < fmu < reduced <
diagnosis. No import runs back up a layer, the imports have no circle (inside functions
either), and every command beyond params/simulate/sweep registers itself through the
'dfa.commands' entry points (the CLI core imports none of them)."""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("dfa_model", "fmu", "reduced", "diagnosis")


def modules() -> dict:
    out = {}
    for pkg in LAYERS:
        for f in (ROOT / pkg).rglob("*.py"):
            name = ".".join(f.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = f
    return out


def extension(package: str, name: str) -> bool:
    """Whether package.name is a compiled extension module (built or not: its sources
    are Python compiled ahead of time, so it is listed by name)."""
    return f"{package}.{name}" in EXTENSIONS


EXTENSIONS = ("dfa_model._kernels_aot",)


def imports(mods: dict, module_level: bool) -> dict:
    """{module: {modules of the four packages it imports}} ('from pkg import sub' counts
    as the submodule, not the package's __init__)."""
    graph = {}
    for m, f in mods.items():
        tree = ast.parse(f.read_text())
        nodes = tree.body if module_level else ast.walk(tree)
        deps = set()
        for node in nodes:
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = m.split(".")
                    keep = len(parts) - node.level + (f.name == "__init__.py")
                    base = ".".join(parts[:keep] + ([node.module] if node.module else []))
                else:
                    base = node.module
                subs = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in mods]
                # a compiled extension (dfa_model._kernels_aot) is a module, not a name of the package
                exts = [a.name for a in node.names if f"{base}.{a.name}" not in mods and extension(base, a.name)]
                targets = subs if len(subs) + len(exts) == len(node.names) else [base, *subs]
            else:
                continue
            for t in targets:
                while t not in mods and "." in t:
                    t = t.rsplit(".", 1)[0]
                if t in mods and t != m:
                    deps.add(t)
        graph[m] = deps
    return graph


def test_no_import_runs_up_a_layer():
    graph = imports(modules(), module_level=False)
    rank = lambda m: LAYERS.index(m.split(".")[0])    # noqa: E731
    upward = sorted((m, d) for m, ds in graph.items() for d in ds if rank(d) > rank(m))
    assert not upward, upward


def test_imports_have_no_circle():
    """No circle, counting the imports inside functions too (a lazy import that closes a
    circle hides a layering the code does not have)."""
    graph = imports(modules(), module_level=False)
    state, cycles = {}, []

    def visit(m, path):
        state[m] = 1
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                cycles.append(path[path.index(d):] + [d])
            elif d not in state:
                visit(d, path + [d])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, cycles


def test_every_command_beyond_the_core_is_an_entry_point():
    """`dfa fmu`, reduce, compare, design, hold and diagnose come from the entry points
    (pyproject.toml), and the parser built with them has exactly those commands."""
    from importlib.metadata import entry_points

    from dfa_model.cli import BUILTIN, build_parser
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"]["dfa.commands"]
    assert set(declared) == {"fmu", "reduce", "compare", "design", "hold", "diagnose"}
    installed = {ep.name: ep.value for ep in entry_points(group="dfa.commands")}
    assert installed == declared, "reinstall (pip install -e .): the installed entry points are stale"
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) == set(BUILTIN) | set(declared)
    core = next(a for a in build_parser(plugins=False)._actions if a.dest == "command")
    assert set(core.choices) == set(BUILTIN)
