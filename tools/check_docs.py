#!/usr/bin/env python3
"""Checks that every reference from the code and the docs resolves to a file and section that exist.

- Markdown links `[text](target)` and images in every Markdown file: the target file exists
  (relative to the file), and a `#anchor` names a heading of the target (GitHub's slug rule).
- Repository paths named in code comments and docs (`docs/design.md`, `tools/plot_run.py`,
  `include/gshaptics/servo/safety.h`, ...): the file exists. Paths under build/, runs/ and
  ../shared/, and paths with placeholders (<...>, *, {..}) are not checked.
- Section citations `docs/design.md Sec. N` (or `Sec. N-M`): docs/design.md has a heading `## N.`.
- No citation of a DESIGN.md or STYLE.md: the repository's design notes are docs/design.md.
- Every script a command runs (`find_tool_script("NAME")` in src/ and apps/) is installed:
  cmake/Install.cmake names tools/NAME, so an installed package finds it in its prefix.
A line that names a path on purpose (a test's temporary tree) says `check_docs: ignore` on it or
on the line before.

Usage: check_docs.py [REPO_ROOT]. Prints one line per broken reference and exits 1, else 0.
"""
import pathlib
import re
import subprocess
import sys

CODE_SUFFIXES = {".h", ".hpp", ".cpp", ".cc", ".c", ".py", ".js", ".sh", ".txt", ".cmake", ".md"}
TOP = ("docs", "bench", "tools", "scripts", "tests", "include", "src", "web", "config", "data",
       "examples", "fuzz", "python", "apps", "cmake", ".ci")
PATH = re.compile(r"(?<![\w./$-])((?:%s)/[\w./+-]*\.[A-Za-z0-9]+)" % "|".join(re.escape(t) for t in TOP))
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
SECTION = re.compile(r"docs/design\.md,?\s+Sec(?:tion|\.)\s*(\d+)(?:\s*-\s*(\d+))?")
FOREIGN = re.compile(r"(?<![\w/.])(DESIGN|STYLE)\.md")


def slug(heading: str) -> str:
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


def headings(md: pathlib.Path):
    out, fence = set(), False
    for line in md.read_text(errors="replace").splitlines():
        if line.startswith("```"):
            fence = not fence
        if not fence and line.startswith("#"):
            out.add(slug(line.lstrip("#")))
    return out


def tracked_files(root: pathlib.Path):
    try:
        names = subprocess.run(["git", "-C", str(root), "ls-files", "--cached", "--others", "--exclude-standard"],
                               capture_output=True, text=True, check=True).stdout.split("\n")
        files = [root / n for n in names if n]
    except (OSError, subprocess.CalledProcessError):
        files = [p for p in root.rglob("*") if p.is_file()]
    return [f for f in files if f.is_file() and "node_modules" not in f.parts and f.parts[len(root.parts)] != "build"]


SCRIPT_CALL = re.compile(r'find_tool_script\("([\w.-]+)"\)')


def uninstalled_scripts(root: pathlib.Path, files):
    install = root / "cmake" / "Install.cmake"
    installed = install.read_text() if install.exists() else ""
    out = []
    for f in files:
        rel = f.relative_to(root)
        if rel.parts[0] not in ("src", "apps"):
            continue
        for n, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
            for name in SCRIPT_CALL.findall(line):
                if f"tools/{name}" not in installed:
                    out.append(f"{rel}:{n}: runs tools/{name}, which cmake/Install.cmake does not install")
    return out


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent.parent).resolve()
    design = root / "docs" / "design.md"
    design_sections = set()
    if design.exists():
        for line in design.read_text().splitlines():
            m = re.match(r"##\s+(\d+)\.", line)
            if m:
                design_sections.add(int(m.group(1)))
    bad = []
    files = [f for f in tracked_files(root) if f.suffix in CODE_SUFFIXES]
    for f in files:
        rel = f.relative_to(root)
        if str(rel) in ("tools/check_docs.py", "tests/check_docs_test.py"):  # they name broken paths on purpose
            continue
        text = f.read_text(errors="replace")
        lines = text.splitlines()
        for n, line in enumerate(lines, 1):
            where = f"{rel}:{n}"
            if "check_docs: ignore" in line or (n >= 2 and "check_docs: ignore" in lines[n - 2]):
                continue
            if f.suffix == ".md":
                for target in LINK.findall(line):
                    if re.match(r"^[a-z]+:", target) or target.startswith("#") and not target[1:]:
                        continue
                    path, _, anchor = target.partition("#")
                    dest = (f.parent / path).resolve() if path else f
                    if not dest.exists():
                        bad.append(f"{where}: link to {target}: no such file")
                    elif anchor and dest.suffix == ".md" and anchor not in headings(dest):
                        bad.append(f"{where}: link to {target}: no heading '#{anchor}' in {dest.relative_to(root)}")
            plain = LINK.sub("", line) if f.suffix == ".md" else line  # links were checked above
            for p in PATH.findall(plain):
                if any(c in p for c in "<>*{}") or p.startswith(("build/", "runs/")):
                    continue
                p = p.rstrip(".")
                if not (root / p).exists():
                    bad.append(f"{where}: names {p}, which does not exist")
            for m in SECTION.finditer(line):
                lo = int(m.group(1))
                hi = int(m.group(2) or lo)
                for s in range(lo, hi + 1):
                    if s not in design_sections:
                        bad.append(f"{where}: cites docs/design.md Sec. {s}, which has no such section")
            if f.suffix != ".md" or rel.parts[0] != "bench":
                for m in FOREIGN.finditer(line):
                    bad.append(f"{where}: cites {m.group(0)}, which is not in the repository (the design notes are docs/design.md)")
    bad += uninstalled_scripts(root, files)
    for line in bad:
        print(line)
    print(f"check_docs: {len(files)} files, {len(bad)} broken references")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
