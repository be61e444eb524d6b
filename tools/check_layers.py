#!/usr/bin/env python3
"""Checks that the library's modules include each other only downwards, in pipeline order.

    error, percentile (root) -> io -> scene -> broadphase | narrowphase -> collision -> force
        -> servo -> sim -> fidelity -> net -> ros1 | ros2

A file in include/gshaptics/<module>/ or src/<module>/ may include gshaptics headers of its own
module and of modules earlier in the order; modules on one level (broadphase and narrowphase,
ros1 and ros2) do not include each other. Applications, tests, benchmarks and bindings sit above
all of them. Usage: check_layers.py [REPO_ROOT]; exit 1 and one line per violation otherwise.
"""
import pathlib
import re
import sys

ORDER = [["."], ["io"], ["scene"], ["broadphase", "narrowphase"], ["collision"], ["force"],
         ["servo"], ["sim"], ["fidelity"], ["net"], ["ros1", "ros2"]]
LEVEL = {module: level for level, group in enumerate(ORDER) for module in group}
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]gshaptics/(?:([a-z0-9_]+)/)?[^">]+[">]')


def module_of(path: pathlib.Path, root: pathlib.Path):
    rel = path.relative_to(root).parts
    if rel[0] == "include" and rel[1] == "gshaptics":
        return "." if len(rel) == 3 else rel[2]
    if rel[0] == "src":
        return "." if len(rel) == 2 else rel[1]
    return None


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent.parent)
    files = [p for d in ("include", "src") for p in (root / d).rglob("*")
             if p.suffix in (".h", ".hpp", ".cpp", ".cc")]
    bad = []
    for f in sorted(files):
        mod = module_of(f, root)
        if mod not in LEVEL:
            bad.append(f"{f.relative_to(root)}: module '{mod}' is not in the layer order of {__file__}")
            continue
        for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            dep = m.group(1) or "."
            if dep not in LEVEL:
                bad.append(f"{f.relative_to(root)}:{n}: includes unknown module '{dep}'")
            elif dep != mod and LEVEL[dep] >= LEVEL[mod]:
                bad.append(f"{f.relative_to(root)}:{n}: {mod} (level {LEVEL[mod]}) includes {dep} "
                           f"(level {LEVEL[dep]}): against the order " +
                           " -> ".join("|".join(g) for g in ORDER))
    for line in bad:
        print(line)
    print(f"check_layers: {len(files)} files, {len(bad)} violations")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
