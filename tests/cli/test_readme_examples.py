"""README's command examples followed as written, from a folder of the user's, block by block and in order
within a block: every ``heliostep`` line exits 0 (its Python API block: ``tests/test_docs_examples.py``).

Four lines take minutes as written; they run here in the smaller form :data:`SMALLER` adds to them
(one day, one candidate, one scenario), their figures tested where README names them; the year-field sweep on
a cluster of the user's is not run (:data:`ELSEWHERE`)."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
from pathlib import Path

import pytest

from heliostep_process import HELIOSTEP

PROJECT = Path(__file__).resolve().parents[2]
README = (PROJECT / "README.md").read_text()

#: What a line of the command (by its first two words) gets added to run within the suite's time.
SMALLER = {
    ("heliostep", "end-loss"): ["--days", "355"],  # 21 December; the year: tests/solar/test_endloss.py
    ("heliostep", "field-light"): ["--days", "355"],  # the year: tests/results/light/test_field_light.py
    ("heliostep", "regress"): ["jan21-central"],  # every scenario: tests/results/compare/test_regress.py
    ("heliostep", "size"): ["--days", "21", "--no-band-days", "--candidate", "QSH5718-51-28-101"],
}
#: The year-field sweep (5,110 cases, hours of CPU, on the user's scheduler): its file and axes are checked by
#: tests/sweep/test_sweep.py::test_year_field_example_is_the_full_year_times_13_mirrors.
ELSEWHERE = "scenarios/sweeps/year-field.yaml"


def _blocks() -> list[tuple[str, str]]:
    """(heading, text) of every ``sh`` block, in README's order."""
    found = []
    for match in re.finditer(r"^```sh\n(.*?)^```", README, re.S | re.M):
        heading = re.findall(r"^#+ (.*)$", README[: match.start()], re.M)[-1]
        found.append((heading, match.group(1)))
    return found


def _commands(text: str) -> list[list[str]]:
    """The ``heliostep`` command lines of a shell block, comments dropped; of an install line, the
    command after its last ``&&`` (the test suite's own line is not run from within it)."""
    commands = []
    for line in text.splitlines():
        words = shlex.split(line.split("&&")[-1], comments=True)
        if words and Path(words[0]).name == "heliostep":
            commands.append(["heliostep", *words[1:]])
    return commands


def _local(word: str) -> str:
    return str(PROJECT / word) if word.startswith("scenarios/") else word


BLOCKS = _blocks()


def test_readme_examples_are_all_found():
    assert BLOCKS[0][0] == "Two commands"
    run_lines = [words for _, text in BLOCKS for words in _commands(text)]
    assert len(run_lines) == 12, run_lines  # README's twelve heliostep lines
    used = {tuple(words[:2]) for words in run_lines}
    assert set(SMALLER) <= used, set(SMALLER) - used  # every smaller form still names a README line


@pytest.mark.parametrize(("heading", "text"), BLOCKS, ids=[f"{i}-{b[0]}" for i, b in enumerate(BLOCKS)])
def test_readme_block_passes_when_followed_in_order(heading, text, tmp_path, fmu_paths):
    environment = {**os.environ, "HELIOSTEP_FMUS": str(tmp_path / "fmus")} if "build-fmus" in text else None
    for words in _commands(text):
        line = [_local(word) for word in words] + SMALLER.get((words[0], words[1]), [])
        if str(PROJECT / ELSEWHERE) in line:
            continue
        done = subprocess.run([*HELIOSTEP, *line[1:]], cwd=tmp_path, capture_output=True, text=True, env=environment)
        assert done.returncode == 0, (shlex.join(words), done.stdout[-2000:], done.stderr[-2000:])
        if "--out" in line:
            out = tmp_path / line[line.index("--out") + 1]
            assert out.is_dir() and any(out.iterdir()), shlex.join(words)
        if words[1] == "compare":
            assert (tmp_path / "report").is_dir()
