"""Write the README's parameter reference from the schema (bracing_core.schema).

python tools/param_reference.py          # rewrite the block in README.md
python tools/param_reference.py --check  # exit 1 if it is stale
"""

from __future__ import annotations

import sys
from pathlib import Path

from bracing_core.schema import reference_markdown

README = Path(__file__).resolve().parents[1] / "README.md"
BEGIN, END = "<!-- parameters: begin (tools/param_reference.py) -->\n", "<!-- parameters: end -->"


def main() -> int:
    text = README.read_text()
    head, rest = text.split(BEGIN)
    _, tail = rest.split(END)
    new = head + BEGIN + reference_markdown() + END + tail
    if "--check" in sys.argv:
        return 0 if new == text else 1
    README.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
