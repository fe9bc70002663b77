"""A hash of the source a result depends on, found by following imports, so caches never outlive their code.

A cached study or a sweep cell is keyed on the code that computed it. Listing those modules by hand goes stale
the first time a module moves; following the imports (in function bodies too, and the dotted paths of modules
imported later, as the registry names its families' engines) from the entry point cannot.
"""
from __future__ import annotations

import ast
import hashlib
import re
from functools import cache
from pathlib import Path

ROOT_PACKAGE = "roughsense"


#: A module named by dotted path to be imported later ("roughsense.model.pls.family:PLSFamily"): a dependency too.
_LAZY = re.compile(rf"{ROOT_PACKAGE}(\.\w+)+:\w+")
#: The installed package's folder: modules are found as files, without importing (or running) any of them.
PACKAGE_DIR = Path(__file__).resolve().parents[1]


def _source(module: str) -> Path | None:
    parts = module.split(".")
    if parts[0] != ROOT_PACKAGE:
        return None
    base = PACKAGE_DIR.joinpath(*parts[1:])
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _runtime_nodes(tree: ast.AST):
    """Every node but those under ``if TYPE_CHECKING:``, which name types and run nothing."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            test = child.test if isinstance(child, ast.If) else None
            if test is not None and "TYPE_CHECKING" in ast.unparse(test):
                todo.extend(child.orelse)
                continue
            todo.append(child)


def _imported(module: str, path: Path) -> set[str]:
    """Every roughsense module that ``module`` imports anywhere in its file, with the packages on the way."""
    package = module if _is_package(path) else module.rpartition(".")[0]
    found: set[str] = set()
    for node in _runtime_nodes(ast.parse(path.read_bytes())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join([*base, *([node.module] if node.module else [])])
            else:
                target = node.module or ""
            found.add(target)
            found.update(f"{target}.{alias.name}" for alias in node.names)  # a submodule imported by name
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and _LAZY.fullmatch(node.value):
            found.add(node.value.partition(":")[0])  # imported when first asked for (the registry's engines)
    closed: set[str] = set()
    for name in found:
        parts = name.split(".")
        if parts[0] == ROOT_PACKAGE:
            closed.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))
    return {name for name in closed if _source(name) is not None}


@cache
def module_closure(*entry_points: str) -> tuple[str, ...]:
    """The entry points and every roughsense module they reach through imports, sorted."""
    seen: set[str] = set()
    todo = list(entry_points)
    while todo:
        module = todo.pop()
        if module in seen:
            continue
        path = _source(module)
        if path is None:
            raise ModuleNotFoundError(f"no source for {module}")
        seen.add(module)
        todo.extend(_imported(module, path) - seen)
    return tuple(sorted(seen))


@cache
def code_fingerprint(*entry_points: str, data_packages: tuple[str, ...] = ()) -> str:
    """12 hex digits of SHA-256 over the closure's sources and the CSV files of ``data_packages``."""
    digest = hashlib.sha256()
    for module in module_closure(*entry_points):
        digest.update(module.encode())
        digest.update(_source(module).read_bytes())
    for package in data_packages:
        folder = PACKAGE_DIR.joinpath(*package.split(".")[1:])
        for item in sorted(folder.glob("*.csv")):
            digest.update(f"{package}/{item.name}".encode())
            digest.update(item.read_bytes())
    return digest.hexdigest()[:12]
