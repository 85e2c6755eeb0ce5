"""The code blocks of README.md and docs/: which run, and how (tests/docs/test_snippets.py runs them).

A ```python block runs; consecutive python blocks of one page share one interpreter, as a reader pasting
them in order would. A ```bash block runs when every command in it is a ``socialnav ...`` or a
``python FILE.py`` command. Markers in an HTML comment on the line right before a block change that:

- ``<!-- not-run: REASON -->``: the block is shown only (a reason is required: needs a GPU, installs
  packages, takes hours...).
- ``<!-- save-as: NAME -->``: the block is written to the file NAME in the page's working directory
  (a module that a later command imports or runs) instead of being run.
- ``<!-- expect-output -->`` before a ```text block: the output of the block before it must contain
  each of its lines (numbers may differ in their last digits: lines are compared with digits masked).

A bash block with another command and no not-run marker is an error, so a shell instruction cannot be
left unchecked by accident.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```(\w*)\s*$")
MARKER = re.compile(r"^<!--\s*(not-run|save-as|expect-output)\s*:?\s*(.*?)\s*-->\s*$")
RUNNABLE_COMMAND = re.compile(r"^(socialnav\s|python\s+[\w./-]+\.py\b)")


@dataclass(frozen=True)
class Block:
    page: str  # path relative to the repository
    line: int  # 1-based line of the opening fence
    lang: str
    code: str
    marker: str | None = None  # not-run, save-as, expect-output
    argument: str = ""  # the marker's reason or file name

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    """README.md and every hand-written page of docs/ (the generated reference pages hold no code)."""
    return [
        ROOT / "README.md",
        *sorted(p for p in (ROOT / "docs").rglob("*.md") if "reference" not in p.parts),
    ]


def blocks(path: Path) -> list[Block]:
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m or not m[1]:
            i += 1
            continue
        start, lang = i, m[1]
        j = i + 1
        while j < len(lines) and lines[j].rstrip() != "```":
            j += 1
        prev = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), "")
        marker = MARKER.match(prev.strip())
        out.append(
            Block(
                str(path.relative_to(ROOT)),
                start + 1,
                lang,
                "\n".join(lines[start + 1 : j]) + "\n",
                marker[1] if marker else None,
                marker[2] if marker else "",
            )
        )
        i = j + 1
    return out


def shell_commands(code: str) -> list[str]:
    """The commands of a bash block: continuation lines joined, comments and blank lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", code)
    commands = []
    for line in joined.splitlines():
        line = line.split(" #", 1)[0].strip() if not line.lstrip().startswith("#") else ""
        if line:
            commands.append(line)
    return commands


def unrunnable_commands(block: Block) -> list[str]:
    return [c for c in shell_commands(block.code) if not RUNNABLE_COMMAND.match(c)]
