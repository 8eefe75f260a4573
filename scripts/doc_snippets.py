"""Runs every ```python block of README.md and the user guide (docs/guide/*.md) as
written, each in a fresh namespace from the repository root, so that no snippet a reader
copies can go stale unnoticed. scripts/test runs it with the installed wheel.

    python scripts/doc_snippets.py [FILE.md ...]
"""

import pathlib
import re
import sys
import time
import traceback

ROOT = pathlib.Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def snippets(path):
    text = path.read_text()
    for m in BLOCK.finditer(text):
        line = text.count("\n", 0, m.start()) + 2
        yield line, m.group(1)


def main(argv):
    files = [pathlib.Path(a).resolve() for a in argv] or [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]
    failed, ran = [], 0
    for path in files:
        for line, code in snippets(path):
            where = f"{path.relative_to(ROOT)}:{line}"
            t0 = time.perf_counter()
            try:
                exec(compile(code, where, "exec"), {"__name__": "__snippet__"})
            except Exception:
                failed.append(where)
                print(f"FAILED {where}", file=sys.stderr)
                traceback.print_exc()
                continue
            ran += 1
            print(f"ok     {where} ({time.perf_counter() - t0:.1f} s)")
    print(f"doc snippets: {ran} passed, {len(failed)} failed")
    return 1 if failed or ran == 0 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
