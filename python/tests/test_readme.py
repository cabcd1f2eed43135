"""The README's Python example runs as it stands from the repository root."""

from __future__ import annotations

import os
import re
from pathlib import Path


def test_readme_python_block_runs(root: Path) -> None:
    text = (root / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1, "one ```python block in the README"
    code = blocks[0]
    assert len(code.strip().splitlines()) <= 12
    cwd = os.getcwd()
    os.chdir(root)
    try:
        exec(compile(code, "README.md", "exec"), {})
    finally:
        os.chdir(cwd)
