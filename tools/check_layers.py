#!/usr/bin/env python3
"""Checks that the library's folders include each other only as the CMake targets link.

Folder = target = layer. Each folder src/<module>/ (and its headers in include/gshaptics/<module>/)
belongs to the one library target whose sources it holds (read from the top-level CMakeLists.txt:
add_library and target_sources); a folder whose sources go to two targets is a violation (a file
there could include what only one of them links), unless one of them is a helper only the other
links. A file may include gshaptics headers of a
module whose target is its own or one its target links to, directly or through others
(target_link_libraries). So
the allowed graph is the build's own: a new include across layers needs a new link, which shows
in review. Inside one target, modules keep a pipeline order (INNER below):

    core:    error, percentile (root) -> broadphase | narrowphase -> io -> scene -> collision -> force
    runtime: servo -> sim

and modules on one level (broadphase and narrowphase) do not include each other. The BVHs and
K_min are geometry that depends on nothing of the scene's, below the loaders: the seen surface
(scene/) finds its Gaussians on a ray through a BVH. Applications,
tests, benchmarks and bindings sit above all of them. Usage: check_layers.py [REPO_ROOT]; exit 1
and one line per violation otherwise.
"""
import pathlib
import re
import sys

INNER = [["."], ["broadphase", "narrowphase"], ["io"], ["scene"], ["collision"], ["force"],
         ["servo"], ["sim"]]
INNER_LEVEL = {m: level for level, group in enumerate(INNER) for m in group}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]gshaptics/(?:([a-z0-9_]+)/)?[^">]+[">]')
COMMAND = re.compile(r'\b(add_library|target_sources|target_link_libraries)\s*\(([^)]*)\)', re.S)


def read_targets(cmake: pathlib.Path):
    """(module -> set of targets, target -> set of gshaptics targets it links)."""
    modules, links = {}, {}
    text = re.sub(r"#[^\n]*", "", cmake.read_text()) if cmake.exists() else ""
    for kind, body in COMMAND.findall(text):
        words = body.split()
        if not words:
            continue
        target = words[0]
        for w in words[1:]:
            if kind in ("add_library", "target_sources"):
                m = re.match(r"src/(?:([a-z0-9_]+)/)?[^/]+\.(?:cpp|cc|c)$", w)
                if m:
                    modules.setdefault(m.group(1) or ".", set()).add(target)
            else:
                dep = re.sub(r"^gshaptics::", "gshaptics_", w)
                if dep.startswith("gshaptics_"):
                    links.setdefault(target, set()).add(dep)
        links.setdefault(target, set())
    return modules, links


def closure(target, links):
    seen, todo = {target}, [target]
    while todo:
        for d in links.get(todo.pop(), ()):
            if d not in seen:
                seen.add(d)
                todo.append(d)
    return seen


def module_of(path: pathlib.Path, root: pathlib.Path):
    rel = path.relative_to(root).parts
    if rel[0] == "include" and rel[1] == "gshaptics":
        return "." if len(rel) == 3 else rel[2]
    if rel[0] == "src":
        return "." if len(rel) == 2 else rel[1]
    return None


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent.parent)
    modules, links = read_targets(root / "CMakeLists.txt")
    reach = {t: closure(t, links) for t in links}
    files = [p for d in ("include", "src") for p in (root / d).rglob("*")
             if p.suffix in (".h", ".hpp", ".cpp", ".cc")]
    bad = []
    for f in sorted(files):
        mod = module_of(f, root)
        if mod not in modules:
            bad.append(f"{f.relative_to(root)}: folder '{mod}' holds no sources of a library target in CMakeLists.txt")
            continue
        # (A helper target that only the folder's main target links is part of it: ros1's
        # transport keeps roscpp's headers out of the bridge's users.)
        mains = [t for t in modules[mod] if not any(t in links.get(o, ()) for o in modules[mod] if o != t)]
        if len(mains) > 1:
            bad.append(f"{f.relative_to(root)}: folder '{mod}' holds sources of several targets "
                       f"({', '.join(sorted(modules[mod]))}): one folder per target")
            continue
        allowed = set().union(*(reach.get(t, {t}) for t in modules[mod]))
        for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            dep = m.group(1) or "."
            if dep == mod:
                continue
            if dep not in modules:
                bad.append(f"{f.relative_to(root)}:{n}: includes '{dep}', a folder of no library target")
            elif not modules[dep] & allowed:
                bad.append(f"{f.relative_to(root)}:{n}: {mod} ({', '.join(sorted(modules[mod]))}) includes {dep} "
                           f"({', '.join(sorted(modules[dep]))}), which its target does not link")
            elif (modules[dep] & modules[mod] and mod in INNER_LEVEL and dep in INNER_LEVEL
                  and INNER_LEVEL[dep] >= INNER_LEVEL[mod]):
                bad.append(f"{f.relative_to(root)}:{n}: {mod} (level {INNER_LEVEL[mod]}) includes {dep} "
                           f"(level {INNER_LEVEL[dep]}) inside one target: against the order " +
                           " -> ".join("|".join(g) for g in INNER))
    for line in bad:
        print(line)
    print(f"check_layers: {len(files)} files, {len(modules)} folders in {len(links)} targets, {len(bad)} violations")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
