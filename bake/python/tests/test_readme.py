"""The README's Python and Mitsuba examples run as written (from the repository root, where a
fresh clone's user runs them), each in a fresh interpreter."""

import re
import subprocess
import sys

import pytest

from conftest import REPO


def blocks(section):
    text = (REPO / "README.md").read_text()
    start = text.index(f"### {section}\n")
    end = text.find("\n#", start + 5)
    found = re.findall(r"```python\n(.*?)```", text[start:end], re.S)
    assert found, f"README.md's section {section!r} has no python example"
    return found


@pytest.mark.parametrize("section", ["Python", "Mitsuba 3"])
def test_readme_examples_run(section, tmp_path):
    for code in blocks(section):
        assert len(code.strip().splitlines()) <= 10, "the README promises ten-line examples"
        # The example writes its image into the working directory: here, into tmp_path instead.
        code = code.replace('"blend.png"', repr(str(tmp_path / "blend.png")))
        subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True, timeout=600)
    if section == "Mitsuba 3":
        assert (tmp_path / "blend.png").stat().st_size > 0
