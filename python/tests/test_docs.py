"""The examples of docs/python.md, run as written (from the repository root, with a folder
of photographs for the folder example)."""

import re
import shutil

import pytest

from conftest import ROOT, SPHERE

BLOCKS = re.findall(r"```python\n(.*?)```", (ROOT / "docs/python.md").read_text(), re.S)


def test_the_page_has_its_examples():
    assert len(BLOCKS) == 3


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_each_example_runs_as_written(index, tmp_path, monkeypatch, capsys):
    # Paths in the examples are the repository's; the folder example reads photos/ and
    # writes features.csv, here in a folder of its own.
    work = tmp_path / "repo"
    work.mkdir()
    for name in ("tests", "models"):
        (work / name).symlink_to(ROOT / name)
    (work / "photos").mkdir()
    for k in range(3):
        shutil.copy(SPHERE, work / "photos" / f"sphere{k}.png")
    monkeypatch.chdir(work)
    exec(compile(BLOCKS[index], f"docs/python.md example {index + 1}", "exec"), {})
    out = capsys.readouterr().out
    if "features.csv" in BLOCKS[index]:
        lines = (work / "features.csv").read_text().splitlines()
        assert len(lines) == 4 and lines[0].startswith("path,pix.mean,pix.var")
        assert out.startswith("(3, 117)")
    if "pyrtools" in BLOCKS[index]:
        assert out.count("wav.s") == 12
