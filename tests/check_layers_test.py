#!/usr/bin/env python3
"""CTest: the repository's includes follow the layer order, and the checker does catch a wrong one."""
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
CHECK = ROOT / "tools" / "check_layers.py"


def run(root):
    return subprocess.run([sys.executable, str(CHECK), str(root)], capture_output=True, text=True)


def main():
    ok = run(ROOT)
    print(ok.stdout, end="")
    assert ok.returncode == 0, "the repository breaks the layer order:\n" + ok.stdout

    with tempfile.TemporaryDirectory() as d:
        t = pathlib.Path(d)
        (t / "include/gshaptics/io").mkdir(parents=True)
        (t / "src/broadphase").mkdir(parents=True)
        (t / "include/gshaptics/io/reader.h").write_text(  # a file of the temporary tree (check_docs: ignore)
            '#include "gshaptics/collision/world.h"\n')
        (t / "src/broadphase/bvh.cpp").write_text('#include "gshaptics/narrowphase/k.h"\n'
                                                  '#include "gshaptics/error.h"\n')
        bad = run(t)
        assert bad.returncode == 1, bad.stdout
        assert "io (level 1) includes collision" in bad.stdout, bad.stdout
        assert "broadphase (level 3) includes narrowphase" in bad.stdout, bad.stdout
        assert "2 violations" in bad.stdout, bad.stdout
    print("1 passed, 0 failed")


if __name__ == "__main__":
    main()
