#!/usr/bin/env python3
"""The import graph of the engine (core/engine/src) and of the add-on (addon/relume).

Prints who imports whom, at the granularity of top-level folders and of files, and fails
(exit 1) when
- files import each other in a circle (in core/engine/src or in addon/relume);
- a module under stack/, geometry/, brdf/ or bssrdf/ imports from bake/ (the bake sits on
  top of them: the vocabulary they share lives on the ground floor of the engine);
- inside bake/, a stage imports a folder it must not (BAKE_STAGE_RULES: the path imports
  no schedule, finishing or farm code, finishing no schedule, and no stage the farm);
- a file of the repository cites a file outside it (../shared/DESIGN.md,
  ../shared/STACK_NOTES.md): the design is docs/design.md.

Rust: a file is a module (`x.rs` or `x/mod.rs`); an import is a `use` of `crate::`,
`super::`, `self::` or a child module, or a `crate::a::b` path written in the code (not the
path of a visibility, `pub(in crate::a)`). A path to
a name that a module only re-exports (`pub use`) leads to the file that defines it. Comments
and string literals are ignored (doc links are not imports).

Python: every `import` and `from … import` in a file, function-local ones included, relative
or absolute through the extension's name (`bl_ext.<repository>.relume`; a plain `relume` is
the compiled bindings); `from . import x` leads to the submodule x when there is one.

Standard library only. `--rust-only`, `--python-only`, `--refs-only` run one part.
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ENGINE = ROOT / "core" / "engine" / "src"
ADDON = ROOT / "addon" / "relume"

# Layers that must not import from the bake: it builds on them.
BELOW_BAKE = ("stack", "geometry", "brdf", "bssrdf")

# Inside the bake: folders (stages) and the folders each must not import from. The path
# traces one eye sample and knows nothing of schedules, finishing or farms; no stage
# depends on the farm, which drives them across machines.
BAKE_STAGE_RULES = {
    "bake/path/": ("bake/schedule/", "bake/finish/", "bake/farm/"),
    "bake/prepare/": ("bake/farm/",),
    "bake/schedule/": ("bake/farm/",),
    "bake/finish/": ("bake/schedule/", "bake/farm/"),
}

# Paths outside the repository that the code and docs once cited.
OUTSIDE_REFERENCES = ("../shared/DESIGN.md", "../shared/STACK_NOTES.md")

# ----------------------------------------------------------------------------------------
# Graph helpers


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's components with more than one node (each one holds at least a circle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[list[str]] = []
    counter = 0
    nodes = sorted(set(graph) | {t for ts in graph.values() for t in ts})
    for root in nodes:
        if root in index:
            continue
        # Iterative depth-first search: (node, iterator over its successors).
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, successors = work[-1]
            advanced = False
            for nxt in successors:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph.get(nxt, ())))))
                    advanced = True
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def shortest_circle(graph: dict[str, set[str]], component: list[str], start: str) -> list[str]:
    """A shortest circle through `start`, staying inside its component."""
    members = set(component)
    previous: dict[str, str] = {}
    frontier = [start]
    seen = {start}
    while frontier:
        following = []
        for node in frontier:
            for nxt in sorted(graph.get(node, ())):
                if nxt not in members:
                    continue
                if nxt == start:
                    circle = [node]
                    while circle[-1] != start:
                        circle.append(previous[circle[-1]])
                    circle.reverse()
                    return circle + [start]
                if nxt not in seen:
                    seen.add(nxt)
                    previous[nxt] = node
                    following.append(nxt)
        frontier = following
    return component


def report_circles(graph: dict[str, set[str]], what: str) -> int:
    """Prints every circle of `graph`; returns how many components hold one."""
    components = strongly_connected(graph)
    if not components:
        print(f"{what}: no import circle")
        return 0
    for component in components:
        print(f"{what}: IMPORT CIRCLE among {len(component)} files: {', '.join(component)}")
        # The shortest circle through each member, each circle once.
        shown = set()
        for start in component:
            circle = shortest_circle(graph, component, start)
            turn = circle[:-1]
            first = turn.index(min(turn))
            canonical = tuple(turn[first:] + turn[:first])
            if canonical not in shown:
                shown.add(canonical)
                print(f"    {' -> '.join(canonical + (canonical[0],))}")
    return len(components)


def print_summary(graph: dict[str, set[str]], unit, title: str) -> None:
    """The graph folded to `unit(file)`: arrows between units, with how many file arrows."""
    folded: dict[tuple[str, str], int] = defaultdict(int)
    for source, targets in graph.items():
        for target in targets:
            a, b = unit(source), unit(target)
            if a != b:
                folded[(a, b)] += 1
    print(f"{title} (arrows between top-level units, file arrows in brackets):")
    by_source: dict[str, list[str]] = defaultdict(list)
    for (a, b), n in sorted(folded.items()):
        by_source[a].append(f"{b} [{n}]")
    for a in sorted(by_source):
        print(f"  {a} -> {', '.join(by_source[a])}")
    units: dict[str, set[str]] = defaultdict(set)
    for a, b in folded:
        units[a].add(b)
    for component in strongly_connected(units):
        print(f"  (top-level units that import each other: {', '.join(component)})")


# ----------------------------------------------------------------------------------------
# Rust


def strip_rust(text: str) -> str:
    """The code without comments, string and char literals (kept as blanks, lines intact)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            end = text.find("\n", i)
            i = n if end < 0 else end
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    if text[i] == "\n":
                        out.append("\n")
                    i += 1
        elif c == "r" and re.match(r'r#*"', text[i:]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r"r(#*)\"", text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            end = n if end < 0 else end + 1 + len(hashes)
            out.append('""' + "\n" * text.count("\n", i, end))
            i = end
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j + 1
        elif c == "'":
            # A char literal ('a', '\n', '\u{..}') or a lifetime ('a): only the former closes.
            m = re.match(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'])'", text[i:])
            if m:
                out.append("' '")
                i += len(m.group(0))
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def rust_modules(src: Path) -> dict[tuple[str, ...], Path]:
    """Module path → file, for every file module under `src`."""
    modules = {}
    for path in sorted(src.rglob("*.rs")):
        parts = path.relative_to(src).with_suffix("").parts
        if parts == ("lib",):
            key: tuple[str, ...] = ()
        elif parts[-1] == "mod":
            key = parts[:-1]
        else:
            key = parts
        modules[key] = path
    return modules


def expand_use_tree(tree: str) -> list[tuple[list[str], str | None]]:
    """`a::{b, c::d, self}` → [a, b], [a, c, d], [a] (globs end in `*`; renames stay `x@y`)."""
    tree = re.sub(r"\s+", "", tree)

    def split_top(s: str) -> list[str]:
        parts, depth, current = [], 0, ""
        for ch in s:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            if ch == "," and depth == 0:
                parts.append(current)
                current = ""
            else:
                current += ch
        if current:
            parts.append(current)
        return parts

    def walk(prefix: list[str], s: str) -> list[tuple[list[str], str | None]]:
        if not s:
            return []
        brace = s.find("{")
        if brace >= 0:
            head = [p for p in s[:brace].split("::") if p]
            inner = s[brace + 1 : s.rfind("}")]
            result = []
            for part in split_top(inner):
                result += walk(prefix + head, part)
            return result
        path = prefix + [p for p in s.split("::") if p]
        if path and path[-1] == "self":
            path = path[:-1]
        return [(path, None)]

    return walk([], tree)


def inline_modules(code: str) -> list[tuple[int, int, str]]:
    """(start, end, name) of every `mod name { … }` written inside a file."""
    found = []
    for m in re.finditer(r"\bmod\s+([A-Za-z_][A-Za-z0-9_]*)\s*\{", code):
        depth, i = 0, m.end() - 1
        while i < len(code):
            if code[i] == "{":
                depth += 1
            elif code[i] == "}":
                depth -= 1
                if depth == 0:
                    break
            i += 1
        found.append((m.start(), i, m.group(1)))
    return found


PATH_RE = re.compile(r"(?<![A-Za-z0-9_:])((?:crate|super|self|[a-z_][a-z0-9_]*)(?:::[A-Za-z_][A-Za-z0-9_]*)+)")
USE_RE = re.compile(r"\b(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);")
# A visibility restricted to a path (`pub(in crate::bake)`) names a module but imports nothing.
VIS_IN_RE = re.compile(r"\bpub\s*\(\s*in\s+[^)]*\)")
DEF_RE = re.compile(r"\b(?:struct|enum|fn|const|static|type|trait|union|mod|macro_rules!)\s+([A-Za-z_][A-Za-z0-9_]*)")


class RustCrate:
    def __init__(self, src: Path):
        self.src = src
        self.modules = rust_modules(src)
        self.code = {key: strip_rust(path.read_text(encoding="utf-8")) for key, path in self.modules.items()}
        self.defined = {key: set(DEF_RE.findall(code)) for key, code in self.code.items()}
        # Per module: (use path as written, is public) after expansion to absolute paths.
        self.uses: dict[tuple[str, ...], list[tuple[list[str], str | None, bool]]] = {}
        self.inline = {key: inline_modules(code) for key, code in self.code.items()}
        for key, code in self.code.items():
            found = []
            for m in USE_RE.finditer(code):
                public = m.group(1) is not None
                scope = key + self.inline_path(key, m.start())
                for path, alias in self._expand(m.group(2)):
                    absolute = self.absolute(scope, path)
                    if absolute is not None:
                        found.append((absolute, alias, public))
            self.uses[key] = found

    def inline_path(self, key: tuple[str, ...], position: int) -> tuple[str, ...]:
        """The inline modules (`mod tests { … }`) of file `key` around `position`."""
        return tuple(name for start, end, name in self.inline[key] if start <= position < end)

    @staticmethod
    def _expand(body: str) -> list[tuple[list[str], str | None]]:
        results = []
        body = body.strip().lstrip(":")
        # Rename `x as y` to a marker expand_use_tree keeps through whitespace removal.
        body = re.sub(r"\s+as\s+", "@", body)
        for path, _ in expand_use_tree(body):
            alias = None
            if path and "@" in path[-1]:
                name, alias = path[-1].split("@", 1)
                path = path[:-1] + [name]
            elif path:
                alias = path[-1]
            results.append((path, alias))
        return results

    def absolute(self, key: tuple[str, ...], path: list[str]) -> list[str] | None:
        """The crate-absolute path of `path` written in module `key`; None if external."""
        if not path:
            return None
        head = path[0]
        if head == "crate":
            return path[1:]
        if head in ("self", "super"):
            base = list(key)
            rest = list(path)
            while rest and rest[0] in ("self", "super"):
                if rest.pop(0) == "super":
                    base = base[:-1]
            return base + rest
        if tuple(key) + (head,) in self.modules:
            return list(key) + path
        return None

    def resolve(self, path: list[str], depth: int = 0) -> tuple[str, ...]:
        """The module (file) defining what `path` names, following `pub use` re-exports."""
        for length in range(len(path), -1, -1):
            module = tuple(path[:length])
            if module in self.modules:
                break
        rest = path[len(module) :]
        if not rest or depth > 8 or rest[0] in self.defined.get(module, ()):
            return module
        for target, alias, public in self.uses.get(module, ()):
            if not public:
                continue
            if alias == rest[0] and target[-1] != "*":
                return self.resolve(target + rest[1:], depth + 1)
        for target, _, public in self.uses.get(module, ()):
            if public and target and target[-1] == "*":
                found = self.resolve(target[:-1] + rest, depth + 1)
                if found != tuple(target[:-1]) or rest[0] in self.defined.get(found, ()):
                    return found
        return module

    def graph(self) -> dict[str, set[str]]:
        names = {key: self.name(key) for key in self.modules}
        graph: dict[str, set[str]] = {names[key]: set() for key in self.modules}
        for key, code in self.code.items():
            targets = set()
            for absolute, _, _ in self.uses[key]:
                targets.add(self.resolve([p for p in absolute if p != "*"]))
            # Paths in the code: crate::…, super::…, self::…, child::….
            use_spans = list(USE_RE.finditer(code)) + list(VIS_IN_RE.finditer(code))
            for m in PATH_RE.finditer(code):
                if any(u.start() <= m.start() < u.end() for u in use_spans):
                    continue
                path = m.group(1).split("::")
                absolute = self.absolute(key + self.inline_path(key, m.start()), path)
                if absolute is not None:
                    targets.add(self.resolve(absolute))
            targets.discard(key)
            graph[names[key]] = {names[t] for t in targets if t in names}
        return graph

    def name(self, key: tuple[str, ...]) -> str:
        return self.modules[key].relative_to(self.src).as_posix()


def top_level(file: str) -> str:
    return file.split("/", 1)[0] + "/" if "/" in file else file


def check_rust() -> int:
    crate = RustCrate(ENGINE)
    graph = crate.graph()
    print(f"== Rust: core/engine/src ({len(graph)} files, {sum(map(len, graph.values()))} file arrows)")
    print_summary(graph, top_level, "top-level folders and files")
    failures = report_circles(graph, "core/engine/src")
    upward = sorted(
        (source, target)
        for source, targets in graph.items()
        for target in targets
        if source.split("/", 1)[0] in BELOW_BAKE and "/" in source and target.startswith("bake/")
    )
    for source, target in upward:
        print(f"core/engine/src: {source} imports {target}: the bake builds on {top_level(source)}, not the reverse")
    if not upward:
        print(f"core/engine/src: nothing under {', '.join(d + '/' for d in BELOW_BAKE)} imports from bake/")
    across = sorted(
        (source, target)
        for source, targets in graph.items()
        for target in targets
        for stage, barred in BAKE_STAGE_RULES.items()
        if source.startswith(stage) and target.startswith(barred)
    )
    for source, target in across:
        print(f"core/engine/src: {source} imports {target}, which its stage must not")
    if not across:
        print(
            "core/engine/src: bake/path/ imports no schedule, finishing or farm code, "
            "bake/finish/ no schedule, and no stage imports bake/farm/"
        )
    return failures + len(upward) + len(across)


# ----------------------------------------------------------------------------------------
# Python


def python_modules(package: Path) -> dict[str, Path]:
    modules = {}
    for path in sorted(package.rglob("*.py")):
        parts = (package.name,) + path.relative_to(package).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def extension_module(name: str, package: str) -> str:
    """The add-on module an absolute import names, or "" for anything else.

    Installed, the add-on is `bl_ext.<repository>.relume`; a plain `import relume` is the
    compiled bindings (core/py), not the add-on.
    """
    parts = name.split(".")
    if len(parts) >= 3 and parts[0] == "bl_ext" and parts[2] == package:
        return ".".join(parts[2:])
    return ""


def imported_modules(modules: dict[str, Path], module: str, names: list[str]) -> set[str]:
    """What `from module import names` loads of the add-on: each name's submodule, else `module`."""
    found = set()
    for imported in names:
        sub = f"{module}.{imported}" if module else imported
        if sub in modules:
            found.add(sub)
        elif module in modules:
            found.add(module)
    if not names and module in modules:
        found.add(module)
    return found


def python_graph(package: Path) -> dict[str, set[str]]:
    modules = python_modules(package)
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        targets: set[str] = set()

        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    module = extension_module(alias.name, package.name)
                    if module in modules:
                        targets.add(module)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = extension_module(node.module or "", package.name)
                targets.update(imported_modules(modules, module, [a.name for a in node.names if a.name != "*"]))
        targets.discard(name)
        graph[name] = targets
    return graph


def check_python() -> int:
    graph = python_graph(ADDON)
    print(f"== Python: addon/relume ({len(graph)} modules, {sum(map(len, graph.values()))} module arrows)")

    def unit(module: str) -> str:
        parts = module.split(".")
        return ".".join(parts[:2]) if len(parts) > 1 else module

    print_summary(graph, unit, "modules (packages folded)")
    return report_circles(graph, "addon/relume")


# ----------------------------------------------------------------------------------------
# References outside the repository


def check_references() -> int:
    print("== references to files outside the repository")
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True).stdout.decode(
            "utf-8", "replace"
        )
        files = [ROOT / f for f in listed.split("\0") if f]
    except (OSError, subprocess.CalledProcessError):
        files = [p for p in ROOT.rglob("*") if p.is_file() and ".git" not in p.parts and "target" not in p.parts]
    me = Path(__file__).resolve()
    found = 0
    for path in files:
        if path.resolve() == me or not path.is_file():
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            for reference in OUTSIDE_REFERENCES:
                if reference in line:
                    where = f"{path.relative_to(ROOT)}:{number}"
                    print(f"{where}: cites {reference}, outside the repository (the design is docs/design.md)")
                    found += 1
    if not found:
        print(f"no file cites {' or '.join(OUTSIDE_REFERENCES)}")
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    only = parser.add_mutually_exclusive_group()
    only.add_argument("--rust-only", action="store_true", help="only the engine's graph")
    only.add_argument("--python-only", action="store_true", help="only the add-on's graph")
    only.add_argument("--refs-only", action="store_true", help="only the outside-reference check")
    args = parser.parse_args()
    everything = not (args.rust_only or args.python_only or args.refs_only)
    failures = 0
    if everything or args.rust_only:
        failures += check_rust()
    if everything or args.python_only:
        failures += check_python()
    if everything or args.refs_only:
        failures += check_references()
    if failures:
        sys.stdout.flush()
        print(f"import graph: {failures} problem(s)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
