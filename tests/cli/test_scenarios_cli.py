"""``heliostep scenarios`` lists the shipped scenarios (name and description, one line each); a misspelt
shipped scenario's name is exit 2 naming the close names (``heliostep run jan21-centrl``)."""

from __future__ import annotations

import pytest
import yaml

from heliostep.cli import main
from heliostep.paths import scenarios_dir


def _shipped() -> dict[str, str]:
    """name -> description of every scenario file shipped, read here (not the regress tolerances)."""
    documents = {path.stem: yaml.safe_load(path.read_text()) for path in sorted(scenarios_dir().glob("*.yaml"))}
    return {name: data["description"] for name, data in documents.items() if "name" in data}


def test_scenarios_lists_every_shipped_scenario_with_its_description(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    shipped = _shipped()
    assert len(shipped) >= 8 and "jan21-weak-motor" in shipped
    assert lines[0] == f"{scenarios_dir()}: {len(shipped)} scenarios"
    assert lines[1].split() == ["name", "description"]
    listed = {line.split()[0]: " ".join(line.split()[1:]) for line in lines[2:]}
    assert listed == {name: " ".join(text.split()) for name, text in shipped.items()}
    assert "regress-tolerances" not in listed


@pytest.mark.parametrize(
    "command, typed, close",
    [
        (["run"], "jan21-centrl", "jan21-central"),
        (["run"], "scenarios/jan21-windi.yaml", "jan21-windy"),
        (["size", "--design-gust", "30"], "jan21-weak-motr", "jan21-weak-motor"),
    ],
)
def test_a_misspelt_scenario_name_is_exit_2_naming_the_close_ones(command, typed, close, tmp_path, capsys):
    out = tmp_path / "out"
    assert main([command[0], typed, *command[1:], "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{typed}: scenario file not found" in err
    assert f"(close: {close})" in err and "heliostep scenarios" in err
    assert "jan21-48v" not in err  # only the close ones, not every shipped name
    assert not out.exists()


def test_a_missing_path_outside_a_scenarios_folder_is_named_without_suggestions(tmp_path, capsys):
    missing = tmp_path / "jan21-centrl.yaml"
    assert main(["run", str(missing)]) == 2
    assert capsys.readouterr().err == f"heliostep run: error: {missing}: scenario file not found\n"
