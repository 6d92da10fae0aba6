"""Static checks of the package as part of the test command: ruff (rules and line length in
pyproject.toml, [tool.ruff]) on navsim, envs and fmu, mypy on the same three (configuration
and its documented per-module exceptions in pyproject.toml, [tool.mypy]), and an AST walk that
fails on a public function or method without annotations or a dataclass field typed as
bare ``object`` (the annotation claim of the README, kept from rotting)."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tool(name: str) -> list[str]:
    exe = Path(sys.executable).with_name(name)
    if exe.exists():
        return [str(exe)]
    found = shutil.which(name)
    if found is None:
        pytest.skip(f"{name} is not installed (it is in the 'test' extra)")
    return [found]


def test_ruff_is_clean_on_the_package():
    out = subprocess.run([*_tool("ruff"), "check", "--no-cache", "navsim", "envs", "fmu"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr


def test_mypy_passes_on_the_package_and_its_faces(tmp_path):
    out = subprocess.run([*_tool("mypy"), "--cache-dir", str(tmp_path / "mypy_cache")], cwd=ROOT,
                         capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Success" in out.stdout


# -- the annotation walk ---------------------------------------------------------------------

PACKAGES = ("navsim", "envs", "fmu")

# Modules (paths relative to the repository) that still have public functions without
# annotations: the annotation work is partial there. The list may only shrink: a module
# listed here that is complete fails test_pending_annotation_list_is_current.
PENDING: frozenset[str] = frozenset()


def _public(name: str) -> bool:
    return not name.startswith("_") or (name.startswith("__") and name.endswith("__"))


def _is_dataclass(node: ast.ClassDef) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", None)
        if name == "dataclass":
            return True
    return False


def _function_gaps(fn: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> list[str]:
    """The unannotated parts of one signature, by mypy's rule: every parameter but a
    method's first, and the return (an ``__init__`` with an annotated parameter may omit it)."""
    a = fn.args
    params = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    first_implicit = method and params and not any(isinstance(d, ast.Name) and d.id == "staticmethod"
                                                   for d in fn.decorator_list)
    gaps = [p.arg for i, p in enumerate(params) if p.annotation is None and not (i == 0 and first_implicit)]
    gaps += [f"*{v.arg}" for v in (a.vararg, a.kwarg) if v is not None and v.annotation is None]
    typed_param = any(p.annotation is not None for p in params)
    if fn.returns is None and not (fn.name == "__init__" and typed_param):
        gaps.append("return")
    return gaps


def annotation_gaps(path: Path) -> list[str]:
    """Public functions and methods (public names, not nested in a function, in public
    classes) with an unannotated parameter or return, and dataclass fields typed ``object``."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: list[str] = []

    def walk(body: list[ast.stmt], prefix: str, in_class: bool, dataclass_body: bool) -> None:
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if _public(node.name):
                    gaps = _function_gaps(node, in_class)
                    if gaps:
                        out.append(f"{path}:{node.lineno} {prefix}{node.name}: {', '.join(gaps)}")
            elif isinstance(node, ast.ClassDef):
                if _public(node.name):
                    walk(node.body, f"{prefix}{node.name}.", True, _is_dataclass(node))
            elif isinstance(node, ast.AnnAssign) and dataclass_body:
                if isinstance(node.annotation, ast.Name) and node.annotation.id == "object":
                    out.append(f"{path}:{node.lineno} {prefix}{ast.unparse(node.target)}: field typed object")
            elif isinstance(node, ast.If):  # TYPE_CHECKING / version branches
                walk(node.body + node.orelse, prefix, in_class, dataclass_body)
            elif isinstance(node, ast.Try):
                walk(node.body + node.orelse + node.finalbody
                     + [s for h in node.handlers for s in h.body], prefix, in_class, dataclass_body)

    walk(tree.body, "", False, False)
    return out


def _modules() -> list[Path]:
    return sorted(p.relative_to(ROOT) for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def test_annotation_walk_finds_the_gaps_it_is_meant_to(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text(
        "from dataclasses import dataclass\n"
        "def f(x, y: int) -> int: ...\n"
        "def g(x: int): ...\n"
        "def _private(x): ...\n"
        "class C:\n"
        "    def __init__(self, a: int): ...\n"
        "    def m(self, b): ...\n"
        "    @staticmethod\n"
        "    def s(c: int) -> None: ...\n"
        "    def __len__(self): ...\n"
        "@dataclass\n"
        "class D:\n"
        "    a: object\n"
        "    b: int = 0\n", encoding="utf-8")
    found = [line.split(" ", 1)[1] for line in annotation_gaps(probe)]
    assert found == ["f: x", "g: return", "C.m: b, return", "C.__len__: return", "D.a: field typed object"]


def test_public_functions_and_dataclass_fields_are_annotated():
    gaps = [g for p in _modules() if str(p) not in PENDING for g in annotation_gaps(ROOT / p)]
    assert not gaps, f"{len(gaps)} unannotated public signatures or object-typed fields:\n" + "\n".join(gaps)


def test_pending_annotation_list_is_current():
    modules = {str(p) for p in _modules()}
    assert PENDING <= modules, f"not modules: {sorted(PENDING - modules)}"
    done = sorted(m for m in PENDING if not annotation_gaps(ROOT / m))
    assert not done, f"fully annotated now, remove from PENDING: {done}"
