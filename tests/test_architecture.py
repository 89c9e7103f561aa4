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
