#!/usr/bin/env python3
"""Part of install_test: the installed `gshaptics serve` serves the page from its install prefix,
and every file the page loads (its relative module imports and links) is installed.
Usage: install_serve_check.py PREFIX DATA_DIR"""
import pathlib
import re
import subprocess
import sys
import time
import urllib.request

prefix, data = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
web = prefix / "share" / "gshaptics" / "web"
# Every relative module, script and stylesheet the page names is in the installed page.
names = set()
for f in ("index.html", "app.js", "xr.js"):
    text = (web / f).read_text()
    names |= set(re.findall(r"""(?:from|import)\s*["']\./([\w./-]+)["']""", text))
    names |= set(re.findall(r"""(?:src|href)=["']\.?/?([\w-]+\.(?:js|css))["']""", text))
missing = [n for n in sorted(names) if not (web / n).exists()]
assert not missing, f"not installed in {web}: {missing}"
assert names, "found no file the page loads: the check would pass whatever is installed"

proc = subprocess.Popen([str(prefix / "bin" / "gshaptics"), "serve", str(data / "truck.splat"),
                         "--registration", str(data / "truck.registration.json"), "--device", "sim",
                         "--port", "0", "--no-token", "--duration", "20", "--quiet", "--no-plot",
                         "--out", str(prefix.parent / "serve-out")],
                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
try:
    lines, url, page = [], None, None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and url is None:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if line.startswith("page "):
            page = line.split(None, 1)[1].strip()
        m = re.match(r"viewer\s+(http://\S+?)/", line)
        if m:
            url = m.group(1)
    assert url, "serve printed no URL:\n" + "".join(lines)
    assert pathlib.Path(page).resolve() == web.resolve(), f"serves {page}, not the installed page {web}"
    for name in ["index.html"] + sorted(names):
        with urllib.request.urlopen(f"{url}/{name}", timeout=10) as r:
            assert r.status == 200 and len(r.read()) > 0, name
    print(f"installed page {web}: {len(names) + 1} files served")
finally:
    proc.terminate()
    proc.wait(timeout=30)
