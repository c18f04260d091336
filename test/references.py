"""What the docstrings of ``gait_biofeedback/`` (and ``benchmarks/``, ``scripts/``) and the pages of
``docs/`` point at, resolved without importing anything: file paths (``core/joints/alignment.py``,
``docs/conventions.md``, ``DESIGN.md``) and Python symbols (``gait_biofeedback.core.params.RENAMED``,
``:class:`StreamSequencer```, ``:meth:`Released.gap_s```, ``core/calibration/walk.py: stance_phases``).
Used by test_docs.py.

A symbol is looked up in the modules' syntax trees: a module's top-level definitions, assignments and
imports (an imported name is followed to the module it comes from), a class's methods, class-level
fields and the ``self.<name>`` attributes its methods assign, and its bases' members. Paths of files
that a session writes (``output/mine``, ``calibration.yaml``) or that lie outside the repository
(``../shared/data``) are not references to check: only paths under a folder of this repository, a
``.md`` page or a ``.py`` module are.
"""

from __future__ import annotations

import ast
import builtins
import functools
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "gait_biofeedback"

_EXTENSIONS = ("py", "md", "yaml", "yml", "msg", "srv", "sh", "toml", "cfg", "js", "html", "css")
_FILE = re.compile(r"(?<![\w/.~-])((?:[\w.-]+/)*[\w-]+\.(?:" + "|".join(_EXTENSIONS) + r"))(?![\w/-])")
_DOTTED = re.compile(r"(?<![\w.~/-])gait_biofeedback(?:\.\w+)+")
_ROLE = re.compile(r":(?:func|class|meth|attr|data|mod|exc|obj):`([^`]+)`")
_PATH_SYMBOL = re.compile(r"(?<![\w/.-])((?:\w+/)+\w+)(?:\.py: ?|\.)(\w+)\b")


@dataclass(frozen=True)
class Reference:
    """One pointer found in a text: where (file, and the docstring's owner), what kind, what it names."""

    where: str
    kind: str  # "file" or "symbol"
    target: str

    def __str__(self) -> str:
        return f"{self.where}: {self.kind} {self.target!r}"


def _roots() -> set[str]:
    """First path components that mean "a file of this repository" (top-level folders, the package's
    subpackages and the core's steps, as docstrings write them relative to the package)."""
    roots = {p.name for p in REPO.iterdir() if p.is_dir() and not p.name.startswith(".")} | {".ci"}
    roots |= {p.name for p in PACKAGE.iterdir() if p.is_dir() and p.name != "__pycache__"}
    roots |= {p.name for p in (PACKAGE / "core").iterdir() if p.is_dir() and p.name != "__pycache__"}
    return roots - {"build", "output", "bags", "test-artifacts", "recordings", "session", "install", "log"}


def file_exists(target: str, beside: Path) -> bool | None:
    """Whether a path named in a text exists; None when it is not a path of this repository."""
    target = target.rstrip(".")
    if target.startswith(("./", "../", "/")):
        return None
    if "/" in target:
        if target.split("/", 1)[0] not in _roots():
            return None
        bases = [REPO, PACKAGE, PACKAGE / "core", REPO / "docs", beside]
        return any((base / target).exists() for base in bases)
    if target.endswith(".md"):
        return any((base / target).exists() for base in (REPO, REPO / "docs", REPO / "docs" / "spec", beside))
    if target.endswith(".py"):
        return _py_file_named(target)
    return None


@functools.cache
def _py_file_named(name: str) -> bool:
    return any(p for p in REPO.rglob(name) if ".venv" not in p.parts and "build" not in p.parts)


# --- symbols -----------------------------------------------------------------------------------------

def module_path(name: str) -> Path | None:
    """The source file of a dotted module name of this repository, or None."""
    base = REPO.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


@functools.cache
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text())


def _module_of(path: Path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _target_names(node: ast.AST) -> Iterator[str]:
    if isinstance(node, ast.Name):
        yield node.id
    elif isinstance(node, (ast.Tuple, ast.List)):
        for element in node.elts:
            yield from _target_names(element)


def _scope_names(body: list[ast.stmt]) -> dict[str, ast.AST]:
    """Names a module or class body defines: definitions, assignments, imports (conditional ones too)."""
    names: dict[str, ast.AST] = {}
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names[node.name] = node
        elif isinstance(node, ast.Assign):
            for target in node.targets:
                for name in _target_names(target):
                    names[name] = node
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)) and isinstance(node.target, ast.Name):
            names[node.target.id] = node
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            for alias in node.names:
                names[(alias.asname or alias.name).split(".")[0]] = node
        elif isinstance(node, (ast.If, ast.Try, ast.With, ast.For)):
            inner = list(node.body) + list(getattr(node, "orelse", [])) + list(getattr(node, "finalbody", []))
            for handler in getattr(node, "handlers", []):
                inner += handler.body
            names.update(_scope_names(inner))
    return names


def _self_attributes(cls: ast.ClassDef) -> set[str]:
    """``self.<name> = ...`` (and annotated) assignments in the class's methods."""
    found = set()
    for node in ast.walk(cls):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
            node, (ast.AnnAssign, ast.AugAssign)) else []
        for target in targets:
            if isinstance(target, ast.Attribute) and ast.unparse(target.value) == "self":
                found.add(target.attr)
    return found


def _import_target(node: ast.Import | ast.ImportFrom, name: str, module: str) -> str | None:
    """The dotted name an imported ``name`` stands for."""
    for alias in node.names:
        if (alias.asname or alias.name).split(".")[0] != name:
            continue
        if isinstance(node, ast.Import):
            return alias.name if alias.asname else name
        base = node.module or ""
        if node.level:
            package = module.split(".")
            # a module's package is itself minus its last part; an __init__ is its own package
            package = package[: len(package) - node.level + (1 if module_path(module) and
                                                            module_path(module).name == "__init__.py" else 0)]
            base = ".".join(package + ([base] if base else []))
        return f"{base}.{alias.name}"
    return None


def resolve(dotted: str, _depth: int = 0) -> bool:
    """Whether ``a.b.C.d`` names a module, or a member of one, of this repository (or, imported into
    one, of a package outside it: taken as existing)."""
    if _depth > 8:
        return False
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        path = module_path(".".join(parts[:cut]))
        if path is not None:
            return _resolve_in(path, ".".join(parts[:cut]), parts[cut:], _depth)
    return False


def _resolve_in(path: Path, module: str, rest: list[str], depth: int) -> bool:
    if not rest:
        return True
    names = _scope_names(_tree(path).body)
    node = names.get(rest[0])
    if node is None:
        submodule = module_path(f"{module}.{rest[0]}")
        return submodule is not None and resolve(".".join([module, *rest]), depth + 1)
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        origin = _import_target(node, rest[0], module)
        if origin is None or not origin.startswith("gait_biofeedback"):
            return True  # a name from another package: not this repository's to check
        return resolve(".".join([origin, *rest[1:]]), depth + 1)
    return _member(node, rest[1:], path, module, depth)


def _member(node: ast.AST, rest: list[str], path: Path, module: str, depth: int) -> bool:
    if not rest:
        return True
    if not isinstance(node, ast.ClassDef):
        return False  # members of a function or a value are not looked into
    members = _scope_names(node.body)
    if rest[0] in members:
        return _member(members[rest[0]], rest[1:], path, module, depth)
    if rest[0] in _self_attributes(node) and len(rest) == 1:
        return True
    scope = _scope_names(_tree(path).body)
    for base in node.bases:  # inherited members
        base_name = ast.unparse(base).split("[")[0]
        head = base_name.split(".")[0]
        if head not in scope:
            return True  # a builtin base (dict, tuple, Exception): its members are not checked
        target = f"{module}.{base_name}"
        if isinstance(scope[head], (ast.Import, ast.ImportFrom)):
            origin = _import_target(scope[head], head, module)
            if origin is None or not origin.startswith("gait_biofeedback"):
                return True  # a base from another package (rclpy's Node, NamedTuple): not checked
            target = origin + base_name[len(head):]
        if resolve(".".join([target, *rest]), depth + 1):
            return True
    return False


def resolve_in_module(name: str, module: str, depth: int = 0, owner: str | None = None) -> bool:
    """A name as a docstring of ``module`` writes it (``:class:`X```, ``:meth:`X.y```, ``.sibling``
    relative to the package, or absolute), looked up there, in the class ``owner``, or absolutely."""
    if name.startswith("."):
        package = module.rsplit(".", 1)[0] if module_path(module).name != "__init__.py" else module
        return resolve(package + name)
    if name.startswith("gait_biofeedback"):
        return resolve(name)
    if name.split(".")[0] in dir(builtins):
        return True  # ValueError, dict.get: Python's own
    candidates = [f"{module}.{name}"] + ([f"{module}.{owner}.{name}"] if owner else [])
    return any(resolve(c, depth) for c in candidates)


# --- what a text points at ---------------------------------------------------------------------------

def role_target(text: str) -> str:
    """The target of a reST role's content: ``~a.b`` → a.b, ``text <a.b>`` → a.b, ``f()`` → f."""
    text = text.strip()
    if text.endswith(">") and "<" in text:
        text = text[text.rindex("<") + 1:-1]
    return re.sub(r"\s+", "", text).lstrip("~!").removesuffix("()")


def references_in(text: str) -> Iterator[tuple[str, str]]:
    """(kind, target) of every file path, dotted ``gait_biofeedback.`` name, reST role and
    ``path.py: symbol`` in a text; a role names a symbol even when it has no dot."""
    for match in _FILE.finditer(text):
        yield "file", match.group(1)
    for match in _DOTTED.finditer(text):
        yield "symbol", match.group(0).rstrip(".")
    for match in _ROLE.finditer(text):
        yield "role", role_target(match.group(1))
    for match in _PATH_SYMBOL.finditer(text):
        if match.group(2) not in _EXTENSIONS:
            yield "path-symbol", f"{match.group(1)}:{match.group(2)}"


def docstrings(path: Path) -> Iterator[tuple[str, str | None, str]]:
    """(where, the enclosing class's name or None, text) of every docstring of a module: its own, its
    classes' and functions', and the strings under an assignment that document it."""
    rel = path.relative_to(REPO)

    def walk(node: ast.AST, owner: str | None, prefix: str) -> Iterator[tuple[str, str | None, str]]:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Expr) and isinstance(child.value, ast.Constant) and isinstance(
                    child.value.value, str):
                yield f"{rel}:{child.lineno} {prefix.rstrip('.')}".rstrip(), owner, child.value.value
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                inner = child.name if isinstance(child, ast.ClassDef) and owner is None else owner
                yield from walk(child, inner, f"{prefix}{child.name}.")
            elif isinstance(child, (ast.If, ast.Try)):
                yield from walk(child, owner, prefix)

    yield from walk(_tree(path), None, "")


def _path_symbol_exists(target: str, beside: Path) -> bool | None:
    """``core/calibration/walk.py: stance_phases`` or ``wire/joints.joint_state_angles``: the symbol is
    defined in that module (None when the path is not a module of this repository)."""
    folder, symbol = target.split(":")
    for base in (PACKAGE, PACKAGE / "core", REPO, beside):
        path = base / f"{folder}.py"
        if path.is_file():
            return resolve(f"{_module_of(path)}.{symbol}")
    return None


def broken(where: str, text: str, beside: Path, module: str | None = None,
           owner: str | None = None) -> list[Reference]:
    """The references of ``text`` that point at nothing."""
    out = []
    for kind, target in references_in(text):
        if kind == "file":
            ok = file_exists(target, beside)
        elif kind == "symbol":
            ok = resolve(target)
        elif kind == "role":
            ok = resolve_in_module(target, module, owner=owner) if module else resolve(target)
        else:
            ok = _path_symbol_exists(target, beside)
        if ok is False:
            out.append(Reference(where, "file" if kind == "file" else "symbol", target))
    return out


def broken_in_docstrings() -> list[Reference]:
    """Of the package's docstrings, and of the benchmarks' and scripts' (their figures are cited)."""
    out = []
    sources = [*PACKAGE.rglob("*.py"), *(REPO / "benchmarks").glob("*.py"), *(REPO / "scripts").glob("*.py")]
    for path in sorted(sources):
        module = _module_of(path)
        for where, owner, doc in docstrings(path):
            out += broken(where, doc, path.parent, module, owner)
    return out


def pages() -> list[Path]:
    return [REPO / "README.md", REPO / "CHANGELOG.md", *sorted((REPO / "docs").rglob("*.md"))]


def broken_in_pages() -> list[Reference]:
    out = []
    for path in pages():
        text = re.sub(r"^::: .*$", "", path.read_text(), flags=re.M)  # API directives: the build checks them
        out += broken(str(path.relative_to(REPO)), text, path.parent)
    return out
