"""The import graph of our packages (contract/, fmu/, training/) and its cycles, read with `ast`.

    python tools/import_graph.py            # every module with the modules of ours it imports, then the cycles
    python tools/import_graph.py --cycles   # only the cycles (exit status 1 when there is one)

Every import counts: absolute and relative, at the top of a file or inside a function. An edge
goes to the module named (`from training.data import io` -> training.data.io; `from
training.frames import wrap_angle` -> training.frames); importing a module does not count as
importing its parent packages. tests/test_imports.py asserts the rules on this graph (no cycle,
contract imports nothing of ours, fmu nothing of training, training's layers point down), see
docs/architecture.md.
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Our packages, bottom first.
PACKAGES = ("contract", "fmu", "training")


def module_files(root: Path = ROOT, packages=PACKAGES) -> dict[str, Path]:
    """Dotted module name -> file of every .py file in `packages` under `root` (a package is
    named by its __init__.py)."""
    files = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return files


def _imported_modules(tree: ast.AST, module: str, is_package: bool, known) -> set[str]:
    """The modules in `known` that the import statements of `tree` (anywhere in it) name: for
    `from m import a` m.a when that is a module, else m; for `import m` m."""
    package = module if is_package else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module
            found.update(f"{source}.{a.name}" if f"{source}.{a.name}" in known else source
                         for a in node.names)
    return {name for name in found if name in known and name != module}


def import_graph(root: Path = ROOT, packages=PACKAGES) -> dict[str, set[str]]:
    """Module -> the modules of ours it imports (itself excluded)."""
    files = module_files(root, packages)
    graph = {}
    for module, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        graph[module] = _imported_modules(tree, module, path.name == "__init__.py", files)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle [a, b, ..., a] per strongly connected group of modules that import each other
    (Tarjan's algorithm, iterative), sorted; empty when the graph is acyclic."""
    index, low, on_stack, stack, groups = {}, {}, set(), [], []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        group.add(member)
                        if member == node:
                            break
                    if len(group) > 1:
                        groups.append(group)
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(sorted(graph[child]))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return sorted(_cycle_through(graph, group) for group in groups)


def _cycle_through(graph: dict[str, set[str]], group: set[str]) -> list[str]:
    """A shortest cycle [first, ..., first] through the alphabetically first module of a strongly
    connected `group` (breadth-first search inside the group)."""
    first = min(group)
    parent = {first: None}
    queue = [first]
    for node in queue:
        for child in sorted(graph[node] & group):
            if child == first:
                path = [node]
                while parent[path[-1]] is not None:
                    path.append(parent[path[-1]])
                return path[::-1] + [first]
            if child not in parent:
                parent[child] = node
                queue.append(child)
    raise ValueError(f"{sorted(group)} is not strongly connected")


def main(argv: list[str]) -> int:
    """Print the graph (unless --cycles) and the cycles; exit status 1 when there is a cycle."""
    graph = import_graph()
    if "--cycles" not in argv:
        for module in sorted(graph):
            print(f"{module} -> {', '.join(sorted(graph[module])) or '(nothing of ours)'}")
    found = cycles(graph)
    print(f"{len(graph)} modules, {sum(map(len, graph.values()))} imports, {len(found)} cycle(s)")
    for cycle in found:
        print("cycle: " + " -> ".join(cycle))
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
