"""The README's code runs as written: its Python blocks, and the files its commands name."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", README, flags=re.S | re.M)


def test_the_python_blocks_run(tmp_path, monkeypatch, capsys):
    blocks = _blocks("python")
    assert blocks, "README.md has no python block"
    monkeypatch.chdir(tmp_path)  # the example writes run.parquet
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {"__name__": "__readme__"})
    out = capsys.readouterr().out.split("\n")
    assert out[-2].startswith("completed ")  # the closed-loop example's run completes
    assert (tmp_path / "run.parquet").stat().st_size > 0


@pytest.mark.parametrize("script", sorted(set(re.findall(r"python (examples/\w+\.py)", README))))
def test_the_examples_it_names_exist(script):
    assert (ROOT / script).is_file()
