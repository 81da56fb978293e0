"""Every repository path and heliostep module that README.md and docs/architecture.md name exists.

A path is a backticked word that looks like a file or folder of the repository (``tests/run/test_run.py``,
``benchmarks/bench_run.py``, ``results/figures/solution.py``: relative to the repository, to ``src`` or to
``src/heliostep``; a bare ``kernel.c`` or ``test_ssp_fmi3.py`` anywhere in the repository), a dotted
``heliostep.…`` name (a module, or an attribute of one), or a Markdown link to a local file. Words with
placeholders (``NAME``, ``<command>``), outputs (``out/…``, ``~/.cache/…``) and test ids are reduced to what
can be checked: ``tests/x.py::test_y`` checks ``tests/x.py`` and that it defines ``test_y``.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parents[1]
PACKAGE = PROJECT / "src" / "heliostep"
DOCS = ("README.md", "docs/architecture.md")

#: the first part of a path that makes it the repository's: its top-level entries and heliostep's packages
ROOTS = {p.name for p in PROJECT.iterdir() if not p.name.startswith(".git")} | {
    p.name for p in PACKAGE.iterdir() if p.is_dir() and not p.name.startswith("__")
}
#: bare file names checked anywhere in the repository (other extensions name outputs: trace.csv, summary.json)
SOURCE_SUFFIXES = (".py", ".c", ".h", ".mo", ".md", ".toml")
CODE = re.compile(r"`([^`\n]+)`")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
PLACEHOLDER = re.compile(r"[A-Z]{3,}|<|\*|\.\.\.|…")


def _words(text: str) -> list[str]:
    """The backticked words of ``text``, outside fenced code blocks (commands and YAML, not names)."""
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    return [word.strip() for word in CODE.findall(prose)]


def _path_words(words: list[str]) -> list[str]:
    """The words that name repository files or folders."""
    found = []
    for word in words:
        word = word.split("::")[0].rstrip(",;:")
        if " " in word or "=" in word or PLACEHOLDER.search(word) or word.startswith(("-", "~", "/", "$", "http")):
            continue
        head = word.split("/")[0]
        if "/" in word and head in ROOTS:
            found.append(word)
        elif "/" not in word and word.endswith(SOURCE_SUFFIXES) and not word.startswith("heliostep."):
            found.append(word)
    return found


def _exists(word: str) -> bool:
    """Whether ``word`` is a file or folder of the repository, of ``src`` or of ``src/heliostep``."""
    if "/" not in word:
        return any(PROJECT.rglob(word))
    return any((base / word).exists() for base in (PROJECT, PROJECT / "src", PACKAGE))


def _module_words(words: list[str]) -> list[str]:
    """The dotted heliostep names: ``heliostep.cosim.fmi``, ``heliostep.cli.leave``."""
    return [
        word
        for word in (w.split("(")[0].rstrip(".,") for w in words)
        if re.fullmatch(r"heliostep(\.[A-Za-z_][A-Za-z0-9_]*)+", word)
    ]


def _resolves(name: str) -> bool:
    """Whether ``name`` is a heliostep module or an attribute of one (the longest importable prefix)."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        relative = Path(*parts[1:cut]) if cut > 1 else Path()
        if (PACKAGE / relative).with_suffix(".py").exists() or (PACKAGE / relative / "__init__.py").exists():
            owner = importlib.import_module(".".join(parts[:cut]))
            for attribute in parts[cut:]:
                if not hasattr(owner, attribute):
                    return False
                owner = getattr(owner, attribute)
            return True
    return False


def _test_ids(text: str) -> list[tuple[str, str]]:
    """(file, test function) of every ``tests/….py::test_name`` the text names."""
    return re.findall(r"`(tests/[\w/]+\.py)::\s*(test_\w+)", text)


@pytest.mark.parametrize("doc", DOCS)
def test_every_repository_path_a_document_names_exists(doc):
    text = (PROJECT / doc).read_text()
    words = _path_words(_words(text))
    assert words, f"{doc} names no path: the pattern is wrong"
    missing = sorted({word for word in words if not _exists(word)})
    assert not missing, f"{doc} names paths the repository does not have: {missing}"


@pytest.mark.parametrize("doc", DOCS)
def test_every_local_link_of_a_document_exists(doc):
    path = PROJECT / doc
    links = [link for link in LINK.findall(path.read_text()) if not link.startswith(("http://", "https://"))]
    missing = sorted({link for link in links if not (path.parent / link).exists()})
    assert not missing, f"{doc} links to files the repository does not have: {missing}"


@pytest.mark.parametrize("doc", DOCS)
def test_every_heliostep_module_a_document_names_resolves(doc):
    names = _module_words(_words((PROJECT / doc).read_text()))
    missing = sorted({name for name in names if not _resolves(name)})
    assert not missing, f"{doc} names heliostep modules or attributes that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOCS)
def test_every_test_a_document_names_is_defined_in_its_file(doc):
    missing = []
    for file, test in _test_ids((PROJECT / doc).read_text()):
        source = PROJECT / file
        if not source.exists() or not re.search(rf"def {test}\b", source.read_text()):
            missing.append(f"{file}::{test}")
    assert not missing, f"{doc} names tests that do not exist: {missing}"


def test_the_path_pattern_takes_repository_paths_and_leaves_outputs_and_placeholders():
    words = [
        "tests/run/test_run.py::test_x",
        "results/figures/solution.py",
        "kernel.c",
        "models/NAME.mo",
        "cli/<command>.py",
        "out/jan21-central/",
        "~/.cache/heliostep/fmus",
        "trace.csv",
        "summary.json",
        "--set fmus.motor=X",
        "heliostep.cosim.fmi",
    ]
    assert _path_words(words) == ["tests/run/test_run.py", "results/figures/solution.py", "kernel.c"]
    assert _module_words(["heliostep.cosim.fmi", "heliostep.run_scenario", "sections"]) == [
        "heliostep.cosim.fmi",
        "heliostep.run_scenario",
    ]
    assert _resolves("heliostep.results.figures.solution.SolutionRecorder")
    assert not _resolves("heliostep.results.no_such_module")
    assert not _exists("results/no_such_module.py")
