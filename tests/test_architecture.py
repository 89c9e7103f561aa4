"""The layering of STYLE.md, checked: core code stays free of click, stdout and exits;
`neurotac --help` loads neither pyarrow nor torch."""

import ast
import pathlib
import subprocess
import sys

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "neurotac_cli"
CORE = [p for folder in ("io", "ops", "sim", "model") for p in (PACKAGE / folder).glob("*.py")] + [
    p for p in (PACKAGE / "metrics.py", PACKAGE / "study.py", PACKAGE / "schema.py", PACKAGE / "units.py") if p.exists()
]


@pytest.mark.parametrize("path", CORE, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_core_code_never_imports_click_prints_or_exits(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            assert not any(name.split(".")[0] == "click" for name in names), f"{path.name} imports click"
        if isinstance(node, ast.Call):
            func = node.func
            name = func.id if isinstance(func, ast.Name) else (func.attr if isinstance(func, ast.Attribute) else "")
            owner = func.value.id if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) else ""
            assert name not in ("exit", "quit") or owner not in ("sys", ""), f"{path.name}:{node.lineno} exits"
            if name == "print":
                keywords = {k.arg for k in node.keywords}
                assert "file" in keywords, f"{path.name}:{node.lineno} prints to stdout"


def test_help_imports_neither_pyarrow_nor_torch():
    code = (
        "import sys\nfrom neurotac_cli.cli import cli\n"
        "try:\n    cli(['--help'], prog_name='neurotac')\nexcept SystemExit:\n    pass\n"
        "heavy = [m for m in ('pyarrow', 'torch', 'numpy', 'sklearn') if m in sys.modules]\n"
        "sys.stderr.write(','.join(heavy))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stderr == ""


def test_every_command_module_keeps_heavy_imports_inside_functions():
    for path in (PACKAGE / "commands").glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                for name in names:
                    assert name.split(".")[0] not in ("pyarrow", "torch", "numpy", "sklearn", "scipy", "matplotlib"), (
                        f"{path.name} imports {name} at module level"
                    )


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: pathlib.Path = PACKAGE) -> dict:
    """module -> the neurotac_cli modules it imports, anywhere in its body (imports inside functions
    count: a lazy import hides a circle from the interpreter, not from the reader)."""
    modules = {_module_name(path): path for path in package.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                # `from package import module` imports the module; `from module import name` the module
                targets.update(f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in modules else node.module
                               for alias in node.names)
        graph[name] = sorted(target for target in targets if target in modules and target != name)
    return graph


def find_cycle(graph: dict) -> list:
    """One import circle of `graph` as [a, b, ..., a], or [] when there is none (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for target in graph.get(node, ()):
            if state.get(target) == "open":
                return stack[stack.index(target):] + [target]
            if target not in state:
                found = visit(target)
                if found:
                    return found
        state[node] = "done"
        stack.pop()
        return []

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return []


def test_find_cycle_sees_a_circle_and_only_a_circle():
    assert find_cycle({"a": ["b"], "b": ["c"], "c": ["a"]}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": ["b", "c"], "b": ["c"], "c": []}) == []


def test_no_import_circle_inside_the_package():
    graph = import_graph()
    assert "neurotac_cli.io.camera" in graph and graph["neurotac_cli.io.camera"], "the import graph is empty"
    cycle = find_cycle(graph)
    assert not cycle, "import circle: " + " -> ".join(cycle)


LONGEST_FUNCTION = 60  # lines, decorators excluded


def _is_numba_kernel(node) -> bool:
    """A function compiled by numba (`@njit`, `@numba.njit(...)`, `@jit`): its loops are its point."""
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def long_functions(package: pathlib.Path = PACKAGE) -> list:
    """`path:name (N lines)` of every function longer than LONGEST_FUNCTION, numba kernels aside."""
    found = []
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_numba_kernel(node):
                lines = node.end_lineno - node.lineno + 1
                if lines > LONGEST_FUNCTION:
                    found.append((f"{path.relative_to(package).as_posix()}:{node.name}", lines))
    return found


def test_no_function_is_longer_than_60_lines_outside_the_numba_kernels():
    too_long = [f"{name} ({lines} lines)" for name, lines in long_functions()]
    assert not too_long, "split these functions: " + ", ".join(too_long)


def test_long_functions_sees_a_long_function_and_spares_a_kernel(tmp_path):
    body = "".join(f"    x{i} = {i}\n" for i in range(LONGEST_FUNCTION))
    (tmp_path / "m.py").write_text(f"def long():\n{body}\n\n@njit(cache=True)\ndef kernel():\n{body}")
    assert long_functions(tmp_path) == [("m.py:long", LONGEST_FUNCTION + 1)]
