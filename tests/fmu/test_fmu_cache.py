"""The FMU cache: used read-only, verified before use, repaired, cleared of
killed builds, keyed by build so versions coexist; ``regress`` stopped by SIGTERM leaves no
temporary folder. Real builds (pymoca, CasADi, gcc), real processes and signals."""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from heliostep.cosim import read_fmu
from heliostep.cosim.kernel import library_path
from heliostep.errors import InputError
from heliostep.fmu.build import build_fmu, digest_path, ensure_fmu
from heliostep.paths import models_dir, scenarios_dir

CLI = "from heliostep.cli import console_main; console_main()"
SMALL_MODEL = "PanelMechanicsSmallAngle"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _cli(*args: str, env: dict[str, str], timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], env={**os.environ, **env}, capture_output=True, text=True, timeout=timeout
    )


def _copy_cache(fmu_paths: dict[str, Path], names: tuple[str, ...], target: Path) -> Path:
    """A cache folder ``target/fmus`` holding the session's built FMUs ``names`` (with their
    recorded digests) and ``target/kernels`` the compiled kernel."""
    for name in names:
        source = fmu_paths[name]
        folder = target / "fmus" / source.parent.name
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, folder / source.name)
        shutil.copy2(digest_path(source), folder / digest_path(source).name)
    (target / "kernels").mkdir()
    shutil.copy2(library_path(), target / "kernels" / library_path().name)
    return target / "fmus"


def _read_only(folder: Path, command: list[str]) -> list[str]:
    """``command`` run with ``folder`` read-only: a private read-only bind mount (util-linux
    ``unshare``; works for root too, which file modes do not stop)."""
    unshare = shutil.which("unshare")
    script = 'mount --bind "$0" "$0" && mount -o remount,bind,ro "$0" && exec "$@"'
    wrapped = [unshare or "unshare", "--user", "--map-root-user", "--mount", "sh", "-c", script, str(folder), *command]
    probe = subprocess.run([*wrapped[: -len(command)], "true"], capture_output=True) if unshare else None
    if probe is None or probe.returncode != 0:
        pytest.skip("no unprivileged mount namespace here (unshare --user --mount) to make a folder read-only")
    return wrapped


def test_a_read_only_cache_of_up_to_date_fmus_runs_and_a_stale_one_is_a_clear_error(fmu_paths, tmp_path):
    cache = _copy_cache(fmu_paths, ("StepperMotor", "PanelMechanics"), tmp_path / "cache")
    env = {**os.environ, "HELIOSTEP_FMUS": str(cache)}
    env.pop("HELIOSTEP_MODELS", None)
    run = [sys.executable, "-c", CLI, "run", "jan21-central", "--set", "window.duration=3", "--no-plots"]
    command = _read_only(tmp_path / "cache", [*run, "--out", str(tmp_path / "out")])
    result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "out" / "summary.json").is_file()
    assert not (cache / ".build").exists()  # no lock was taken

    digest_path(next(cache.glob("*/StepperMotor.fmu"))).unlink()  # unverified now: it must be rebuilt
    command = _read_only(tmp_path / "cache", [*run, "--out", str(tmp_path / "out2")])
    result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr[-3000:]
    assert "Traceback" not in result.stderr
    assert f"FMU cache {cache} ($HELIOSTEP_FMUS): cannot build StepperMotor.fmu there" in result.stderr


def test_a_flipped_byte_in_a_cached_fmu_is_found_and_the_fmu_rebuilt(fmu_paths, tmp_path):
    cache = _copy_cache(fmu_paths, (SMALL_MODEL,), tmp_path)
    cached = next(cache.glob(f"*/{SMALL_MODEL}.fmu"))
    original = cached.read_bytes()
    damaged = bytearray(original)
    damaged[len(damaged) // 2] ^= 0x01
    cached.write_bytes(bytes(damaged))

    repaired = ensure_fmu(SMALL_MODEL, fmus=cache)
    assert repaired == cached
    assert repaired.read_bytes() == original  # the build is deterministic: the very bytes of before
    assert digest_path(repaired).read_text().strip() == hashlib.sha256(original).hexdigest()
    assert read_fmu(repaired).model_identifier == SMALL_MODEL


def _middle_of_the_binary(fmu_path):
    """The offset of the middle byte of the FMU's compressed shared library in the archive (its
    local header is 30 bytes, then its name and extra field: PKWARE APPNOTE 4.3.7)."""
    with zipfile.ZipFile(fmu_path) as archive:
        info = next(i for i in archive.infolist() if i.filename.startswith("binaries/"))
    with open(fmu_path, "rb") as handle:
        handle.seek(info.header_offset + 26)
        name_length, extra_length = struct.unpack("<HH", handle.read(4))
    return info.header_offset + 30 + name_length + extra_length + info.compress_size // 2


def test_a_damaged_fmu_of_the_user_is_bad_input_naming_it(fmu_paths, tmp_path):
    dropped = tmp_path / "Vendor.fmu"
    damaged = bytearray(fmu_paths["StepperMotor"].read_bytes())
    damaged[_middle_of_the_binary(fmu_paths["StepperMotor"])] ^= 0x01  # its CRC or its inflation fails
    dropped.write_bytes(bytes(damaged))
    with pytest.raises(InputError, match=rf"{dropped}: a damaged FMU archive"):
        read_fmu(dropped)


def test_a_build_killed_midway_leaves_a_folder_that_the_next_build_clears(fmu_paths, tmp_path):
    cache = tmp_path / "fmus"
    code = f"from heliostep.fmu.build import build_fmu; build_fmu({SMALL_MODEL!r}, {str(cache)!r})"
    builder = subprocess.Popen([sys.executable, "-c", code])
    scratch = cache / ".build"
    deadline = time.monotonic() + 120
    while not list(scratch.glob(f"{SMALL_MODEL}-*")) and time.monotonic() < deadline and builder.poll() is None:
        time.sleep(0.01)
    builder.kill()
    builder.wait()
    left = list(scratch.glob(f"{SMALL_MODEL}-*"))
    assert left and left[0].name.startswith(f"{SMALL_MODEL}-{builder.pid}-")
    assert not list(cache.glob(f"*/{SMALL_MODEL}.fmu.sha256"))  # not counted as built

    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        live = scratch / f"{SMALL_MODEL}-{sleeper.pid}-inprogress"
        live.mkdir()  # a build whose process is alive (another cache user's) is left alone
        built = build_fmu(SMALL_MODEL, cache)
        assert sorted(p.name for p in scratch.glob(f"{SMALL_MODEL}-*")) == [live.name]
    finally:
        sleeper.kill()
        sleeper.wait()
    assert _sha256(built) == _sha256(fmu_paths[SMALL_MODEL])


def test_two_builds_of_one_model_coexist_in_one_cache(tmp_path):
    models = tmp_path / "models"
    shutil.copytree(models_dir(), models)
    cache = tmp_path / "fmus"
    first = build_fmu(SMALL_MODEL, cache, models)
    source = models / f"{SMALL_MODEL}.mo"
    source.write_text(source.read_text().replace('J_p(unit = "kg.m2") = 3.37', 'J_p(unit = "kg.m2") = 4.2'))
    second = build_fmu(SMALL_MODEL, cache, models)  # "another version" of the model, same cache
    assert second != first and first.is_file() and second.is_file()
    assert read_fmu(first).guid != read_fmu(second).guid
    assert read_fmu(first).variables["J_p"].start == 3.37 and read_fmu(second).variables["J_p"].start == 4.2


def test_regress_stopped_by_sigterm_leaves_nothing_in_tmpdir(fmu_paths, tmp_path):
    scenarios = tmp_path / "scenarios"
    scenarios.mkdir()
    for name in ("jan21-day.yaml", "jan21-day.reference.parquet"):
        shutil.copy2(scenarios_dir() / name, scenarios / name)
    private = tmp_path / "tmp"
    private.mkdir()
    env = {**os.environ, "TMPDIR": str(private)}
    command = [sys.executable, "-c", CLI, "regress", str(scenarios / "jan21-day.yaml")]
    process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(private.glob("heliostep-trace-*")) and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.02)  # the day streams its trace to a temporary folder: it is simulating now
    assert list(private.glob("heliostep-fmus-*")) and list(private.glob("heliostep-trace-*"))
    time.sleep(0.3)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + signal.SIGTERM, stderr[-3000:]
    assert "Traceback" not in stderr
    assert sorted(p.name for p in private.iterdir()) == []


def test_a_build_at_first_use_says_so_on_stderr_and_stdout_keeps_the_path_alone(tmp_path):
    # a first build takes seconds: one line on stderr names the FMU and the cache; a second use says nothing
    cache = tmp_path / "fmus"
    first = _cli("build-fmus", "--model", SMALL_MODEL, env={"HELIOSTEP_FMUS": str(cache)})
    assert first.returncode == 0, first.stderr[-3000:]
    assert f"heliostep: building {SMALL_MODEL}.fmu (first use, cached in {cache})\n" in first.stderr
    assert first.stdout == f"{next(cache.glob(f'*/{SMALL_MODEL}.fmu'))}\n"  # stdout: data, the path alone
    again = _cli("build-fmus", "--model", SMALL_MODEL, env={"HELIOSTEP_FMUS": str(cache)})
    assert again.returncode == 0 and "building" not in again.stderr and again.stdout == first.stdout
