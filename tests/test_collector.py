"""Tests of heliostep.collector: a block run without the cyclic garbage collector, what it made frozen after;
and the installed command importing its modules that way (a real ``heliostep`` entry point in a new
interpreter), while ``main`` called from Python leaves its caller's collector alone."""

from __future__ import annotations

import gc
import json
import subprocess
import sys
import textwrap

import pytest

from heliostep.collector import imports_frozen


class Node:
    """A container the collector tracks, in a cycle with itself."""

    def __init__(self):
        self.me = self


@pytest.fixture
def unfrozen():
    """This test process's collector as it was: nothing left frozen, enabled."""
    assert gc.isenabled() and gc.get_freeze_count() == 0
    yield
    gc.unfreeze()
    gc.enable()


def test_the_block_runs_without_the_collector_and_what_it_made_is_frozen_after(unfrozen):
    collections = []

    def count(phase, info):
        if phase == "start":
            collections.append(info["generation"])

    gc.callbacks.append(count)
    try:
        with imports_frozen():
            assert not gc.isenabled()
            made = [Node() for _ in range(50_000)]  # far past generation 0's threshold (2 000 in 3.11-3.13)
            collections_inside = len(collections)
        assert gc.isenabled()
    finally:
        gc.callbacks.remove(count)
    assert collections_inside == 0
    assert gc.get_freeze_count() >= len(made) + 1  # the nodes and their list, and what was alive before
    # frozen means no collection examines them: a full collection finds none of these cycles once dropped
    del made
    assert gc.collect() < 50_000
    gc.unfreeze()
    assert gc.collect() >= 50_000  # unfrozen, the 50 000 cycles are garbage found


def test_an_exception_in_the_block_still_freezes_and_a_disabled_collector_stays_off(unfrozen):
    with pytest.raises(ImportError), imports_frozen():
        raise ImportError("no module named 'matplotlib'")
    assert gc.isenabled() and gc.get_freeze_count() > 0
    gc.unfreeze()
    gc.disable()
    with imports_frozen():
        pass
    assert not gc.isenabled()  # as the caller had it


PROBE = textwrap.dedent(
    """
    import gc, json, sys
    from heliostep import cli
    full_while_importing = []
    gc.callbacks.append(lambda phase, info: phase == "start" and info["generation"] == 2
                        and full_while_importing.append(1))

    def probe(command, args):  # the command's function, once its modules are imported and its line parsed
        print(json.dumps({"frozen": gc.get_freeze_count(), "enabled": gc.isenabled(),
                          "full collections": len(full_while_importing),
                          "imported": "heliostep.run.runner" in sys.modules}), flush=True)
        return 0

    cli._run = probe
    sys.argv = ["heliostep", "run", "scenario.yaml"]
    if ENTRY == "console_main":
        cli.console_main()
    else:
        sys.exit(cli.main())
    """
)


@pytest.mark.parametrize("entry", ["console_main", "main"])
def test_the_installed_command_imports_its_modules_uncollected_and_frozen_and_main_leaves_the_collector(entry):
    done = subprocess.run(
        [sys.executable, "-c", PROBE.replace("ENTRY", repr(entry))],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    seen = json.loads(done.stdout)
    assert seen["imported"] and seen["enabled"]
    if entry == "console_main":
        # the run command's modules (numpy, pandas, scipy, pyarrow, pydantic, fmpy, heliostep's): ~195 000 objects
        assert seen["frozen"] > 100_000 and seen["full collections"] == 0
    else:  # called from Python: imported with the caller's collector on, nothing frozen
        assert seen["frozen"] == 0 and seen["full collections"] >= 1
