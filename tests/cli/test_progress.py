"""Progress goes to standard error, never to standard output (data): a bar on a terminal only (not in CI),
none into a pipe or a closed descriptor, and a one-line note (an FMU built at first use) that a failing
standard error cannot turn into a failure. Real commands, a real pseudo-terminal."""

from __future__ import annotations

import fcntl
import io
import os
import pty
import select
import struct
import subprocess
import termios

import pytest

from heliostep.progress import note, progress_bar
from heliostep_process import HELIOSTEP

END_LOSS = ["end-loss", "--days", "172", "173", "--step-minutes", "30", "--shading-step-minutes", "60", "--no-plots"]


def _on_a_terminal(args: list[str]) -> tuple[int, str, str]:
    """``heliostep ARGS`` with its standard error a pseudo-terminal and its standard output a pipe, CI unset:
    exit status, standard output, what the terminal showed."""
    leader, follower = pty.openpty()
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns (0: no bar drawn)
    env = {key: value for key, value in os.environ.items() if key != "CI"}
    process = subprocess.Popen(HELIOSTEP + args, stdout=subprocess.PIPE, stderr=follower, env=env)
    os.close(follower)
    shown = b""
    while True:  # read the terminal as it goes (a full one would block the command)
        ready, _, _ = select.select([leader], [], [], 300)
        try:
            chunk = os.read(leader, 65536) if ready else b""
        except OSError:  # EIO: the command closed its end
            chunk = b""
        if not chunk:
            break
        shown += chunk
    out = process.stdout.read().decode()
    os.close(leader)
    return process.wait(timeout=300), out, shown.decode(errors="replace")


@pytest.mark.parametrize(
    "args, bar",
    [
        (END_LOSS, "end loss: 100%"),
        (
            ["field-light", "jan21-central", "--days", "172", "173", "--step-minutes", "60", "--no-plots"],
            "field light: 100%",
        ),
    ],
)
def test_a_bar_on_the_terminal_goes_to_stderr_and_stdout_stays_data(args, bar, tmp_path):
    status, out, shown = _on_a_terminal([*args, "--out", str(tmp_path / "out")])
    assert status == 0, shown[-3000:]
    assert bar in shown and "2/2" in shown  # the bar, over the days, on the terminal
    assert "energy" in out and "wrote" in out  # the report, on stdout
    assert "\r" not in out and "|" not in out and bar.split(":")[0] + ":" not in out  # and no bar in it


def test_no_bar_into_a_pipe_and_none_into_a_closed_stderr(tmp_path):
    piped = subprocess.run([*HELIOSTEP, *END_LOSS, "--out", str(tmp_path / "a")], capture_output=True, text=True)
    assert piped.returncode == 0, piped.stderr[-3000:]
    assert "end loss:" not in piped.stderr and "end loss:" not in piped.stdout and "\r" not in piped.stdout
    closed = subprocess.run(  # standard error closed at start (the command fills it with the null device)
        [*HELIOSTEP, *END_LOSS, "--out", str(tmp_path / "b")],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        preexec_fn=lambda: os.close(2),
    )
    assert closed.returncode == 0
    assert "energy on the tube" in closed.stdout and "end loss:" not in closed.stdout


def test_a_note_on_a_failing_stderr_is_lost_not_raised(monkeypatch, capsys):
    class Broken(io.StringIO):
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr("sys.stderr", Broken())
    note("heliostep: building X.fmu (first use, cached in somewhere)")  # no exception
    with progress_bar(3, "quiet", "step") as bar:  # not a terminal: disabled, writes nothing
        bar.update(3)
    monkeypatch.setattr("sys.stderr", None)
    note("nowhere to say it")
    assert capsys.readouterr().out == ""
