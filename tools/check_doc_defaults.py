#!/usr/bin/env python3
"""Checks that every option default the docs state is the default the CLI has.

The CLI's defaults are read from `gshaptics COMMAND --help` (CLI11 prints a captured default as
`[VALUE]`; an on|off option says `Default: VALUE` in its text). The docs' statements are found in
README.md and docs/*.md in these forms:
  --energy-bound on|off (default on)       `--floater-cluster` (default 3; ...)
  (`--device-shading 0.2`, the default     `--tau-max` (0.5 N m by default ...)
  --f-max 30 (N; ...)                      (an option, its value and its unit, as in docs/usage.md's summary)
A stated default that differs from the CLI's is reported with its file and line.

Usage: check_doc_defaults.py GSHAPTICS_BINARY [REPO_ROOT]. Prints one line per mismatch and
exits 1, else 0 (and how many statements it compared, so that a check comparing nothing shows).
"""
import pathlib
import re
import subprocess
import sys

COMMANDS = ("simulate", "run", "serve", "node", "fidelity", "stability", "info", "synth", "query", "poses",
            "convert", "latency", "device-sim")
# "  --stiffness FLOAT:a finite number > 0=1000   proxy: ..." (the type, then =DEFAULT)
HELP_DEFAULT = re.compile(r"^\s*(?:-\w,\s*)?(--[a-z][a-z0-9-]*)\s+(\S(?:.*?\S)?)(?:\s{2,}|$)")
HELP_TEXT_DEFAULT = re.compile(r"Default: ([\w.]+)")
DOC_FORMS = [
    re.compile(r"(--[a-z][a-z0-9-]*) [\w.|]+ \(default ([\w.]+)\)"),
    re.compile(r"`(--[a-z][a-z0-9-]*)` \(default ([\w.]+)"),
    re.compile(r"`(--[a-z][a-z0-9-]*) ([\w.]+)`,? (?:the default|\(the default|\(default\))"),
    re.compile(r"`(--[a-z][a-z0-9-]*)` \(([\d.]+)[^)]*? by default"),
    re.compile(r"(?<![\w`-])(--[a-z][a-z0-9-]*) ([\d.]+) \((?:N|tool|s\b|m\b|Hz)"),
]


def cli_defaults(binary):
    out = {}
    for cmd in COMMANDS:
        text = subprocess.run([binary, cmd, "--help"], capture_output=True, text=True).stdout
        current = None
        for line in text.splitlines():
            m = HELP_DEFAULT.match(line)
            if m and "=" in m.group(2):
                out.setdefault(m.group(1), set()).add(m.group(2).rsplit("=", 1)[1])
            opt = re.match(r"^\s*(?:-\w,\s*)?(--[a-z][a-z0-9-]*)", line)
            if opt:
                current = opt.group(1)
            d = HELP_TEXT_DEFAULT.search(line)
            if d and current:
                out.setdefault(current, set()).add(d.group(1))
    return out


def same(a, b):
    try:
        return float(a) == float(b)
    except ValueError:
        return a == b


def main():
    binary = sys.argv[1]
    root = pathlib.Path(sys.argv[2] if len(sys.argv) > 2 else pathlib.Path(__file__).parent.parent).resolve()
    defaults = cli_defaults(binary)
    if not defaults:
        print(f"check_doc_defaults: {binary} printed no defaults")
        return 1
    docs = [root / "README.md"] + sorted((root / "docs").glob("*.md"))
    bad, compared = [], 0
    for doc in docs:
        for n, line in enumerate(doc.read_text(errors="replace").splitlines(), 1):
            for form in DOC_FORMS:
                for option, stated in form.findall(line):
                    if option not in defaults:
                        continue
                    compared += 1
                    if not any(same(stated, d) for d in defaults[option]):
                        bad.append(f"{doc.relative_to(root)}:{n}: says {option} defaults to {stated}; "
                                   f"the CLI's default is {' or '.join(sorted(defaults[option]))}")
    for b in bad:
        print(b)
    print(f"check_doc_defaults: {compared} stated defaults compared, {len(bad)} differ")
    return 1 if bad or compared == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
