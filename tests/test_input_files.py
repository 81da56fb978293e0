"""A file the user names is read only if it is a regular file within its kind's bound: a directory,
a FIFO, a device or an oversized file is an InputError naming it (never a hang or a read without end)."""

from __future__ import annotations

import os
import subprocess

import pytest

from heliostep.errors import InputError
from heliostep.input_files import MAX_YAML_BYTES, check_input_file, open_input, read_input_bytes
from heliostep.paths import scenarios_dir
from heliostep.results.trace.files import read_trace
from heliostep.scenario import load_scenario
from heliostep_process import HELIOSTEP


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "scenario.yaml"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"scenario.yaml: the scenario file is a named pipe \(FIFO\); expected"):
        load_scenario(fifo)  # before: blocked in open() until a writer came


def test_a_character_device_and_a_directory_are_refused_naming_what_they_are(tmp_path):
    with pytest.raises(InputError, match=r"/dev/zero: the scenario file is a character device; expected a regular"):
        load_scenario("/dev/zero")  # before: read until memory ran out
    (tmp_path / "folder.csv").mkdir()
    with pytest.raises(InputError, match=r"folder.csv: the trace file is a directory; expected a regular file"):
        read_trace(tmp_path / "folder.csv")


def test_a_file_over_its_bound_is_refused_before_it_is_read(tmp_path):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as handle:
        handle.truncate(MAX_YAML_BYTES + 1)  # sparse: no disk taken
    with pytest.raises(InputError, match=r"big.yaml: the scenario file has 16,777,217 bytes; expected at most 16,7"):
        load_scenario(big)
    fine = tmp_path / "fine.bin"
    fine.write_bytes(b"12345")
    assert read_input_bytes(fine, "test", 5) == b"12345"
    with pytest.raises(InputError, match=r"fine.bin: the test file has 5 bytes; expected at most 4 bytes"):
        check_input_file(fine, "test", 4)
    with open_input(fine, "test", 5) as handle:
        assert handle.read() == b"12345"


def test_a_file_reporting_no_size_is_read_only_up_to_the_bound():
    """``/proc`` files are regular with a size of 0: the read itself is bounded."""
    assert len(read_input_bytes("/proc/self/status", "status", 1 << 20)) > 0
    with pytest.raises(InputError, match=r"/proc/self/status: the status file has more than 10 bytes"):
        read_input_bytes("/proc/self/status", "status", 10)


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_run_on_a_fifo_or_dev_zero_exits_2_at_once(kind, tmp_path):
    scenario = "/dev/zero"
    if kind == "fifo":
        scenario = str(tmp_path / "pipe.yaml")
        os.mkfifo(scenario)
    completed = subprocess.run(
        [*HELIOSTEP, "run", scenario, "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 2, completed.stderr
    assert "Traceback" not in completed.stderr and f"{scenario}: the scenario file is a" in completed.stderr
    assert not (tmp_path / "out").exists()


def test_the_shipped_scenario_still_loads():
    assert load_scenario(scenarios_dir() / "jan21-central.yaml").name == "jan21-central"


def test_compare_on_a_csv_of_a_gigabyte_is_refused_before_reading_it(tmp_path, capsys):
    from heliostep.cli import main

    huge = tmp_path / "huge.csv"
    with open(huge, "wb") as handle:  # sparse: a header line of 1 GB that takes no disk
        handle.write(b"time,")
        handle.truncate(10**9)
    small = tmp_path / "small.csv"
    small.write_text("time,x\n0,1\n1,2\n")
    assert main(["compare", str(huge), str(small)]) == 2  # before: MemoryError
    assert "huge.csv: the trace file has 1,000,000,000 bytes; expected at most" in capsys.readouterr().err
