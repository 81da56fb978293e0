"""README's `compare` example, followed as written from a folder of the user's: the paper's case run again
passes against its shipped reference, every signal inside its tube (exit status 0)."""

from __future__ import annotations

import re
import shlex
import subprocess
from pathlib import Path

from heliostep_process import HELIOSTEP

PROJECT = Path(__file__).resolve().parents[2]


def _compare_block() -> list[str]:
    text = (PROJECT / "README.md").read_text()
    section = text[text.index("### `heliostep compare`") :]
    (block,) = re.findall(r"```sh\n(.*?)```", section, re.S)[:1]
    return [line for line in block.splitlines() if line.strip()]


def test_readme_compare_example_passes_when_followed_in_order(tmp_path, fmu_paths):
    lines = _compare_block()
    assert [line.split()[:2] for line in lines] == [["heliostep", "run"], ["heliostep", "compare"]]
    for line in lines:
        words = [str(PROJECT / w) if w.startswith("scenarios/") else w for w in shlex.split(line)]
        done = subprocess.run([*HELIOSTEP, *words[1:]], cwd=tmp_path, capture_output=True, text=True)
        assert done.returncode == 0, (line, done.stdout[-2000:], done.stderr[-2000:])
    assert (tmp_path / "report").is_dir() and (tmp_path / "out" / "central" / "trace.parquet").is_file()
