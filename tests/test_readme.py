"""README.md's Python blocks, each run alone in a fresh interpreter as a reader pastes it: every
block imports what it uses, runs, and where README shows its output (a plain block right after
it) prints exactly that."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import hang

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", re.S | re.M)


def python_blocks(text: str) -> list[tuple[int, str, str | None]]:
    """Each ```python block of ``text``: its first line's number, its code, and the output
    README shows for it (the untagged block that follows it after blank lines only), or None."""
    blocks = []
    fences = list(FENCE.finditer(text))
    for k, fence in enumerate(fences):
        if fence.group(1) != "python":
            continue
        following = fences[k + 1] if k + 1 < len(fences) else None
        shown = None
        if following is not None and following.group(1) == "" and not text[fence.end():following.start()].strip():
            shown = following.group(2)
        blocks.append((text.count("\n", 0, fence.start()) + 2, fence.group(2), shown))
    return blocks


def test_the_block_reader_on_a_made_up_page():
    page = ("# t\n\n```python\nprint(1)\n```\n\n```\n1\n```\n\ntext\n\n```bash\nls\n```\n\n"
            "```python\nx = 2\n```\nsaid between\n```\nnot its output\n```\n")
    assert python_blocks(page) == [(4, "print(1)\n", "1\n"), (18, "x = 2\n", None)]


def test_every_readme_python_block_runs_alone_and_prints_what_readme_shows(tmp_path):
    blocks = python_blocks(README.read_text())
    assert len(blocks) >= 2, "README.md's Gymnasium blocks were not found"
    for line, code, shown in blocks:
        done = hang.run([sys.executable, "-c", code], f"README.md's python block at line {line}", cwd=ROOT,
                        env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "MPLBACKEND": "Agg"})
        assert done.returncode == 0, f"README.md's python block at line {line} fails alone:\n{done.stderr[-3000:]}"
        if shown is not None:
            assert done.stdout == shown, f"README.md line {line}: the block prints\n{done.stdout}\nnot what README shows"
