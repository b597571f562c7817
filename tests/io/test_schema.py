"""The case-file schema: generated reference, template that runs, validator and docs agree."""

import json
from pathlib import Path

import pytest

from signorini.io.cli import main
from signorini.io.config import SECTIONS, load_case
from signorini.io.schema import SECTIONS as SCHEMA
from signorini.io.schema import reference_markdown

ROOT = Path(__file__).resolve().parents[2]


def test_case_file_reference_is_generated_and_up_to_date():
    text = (ROOT / "docs" / "case-files.md").read_text()
    assert text == reference_markdown(), "run python -m signorini.io.doctables --write"
    for s in SCHEMA:
        for k in s.keys:
            assert f"| `{k.name}` |" in text
    for word in ("[[traction]]", "[loads]", "file", "normal", "Expressions", "--set"):
        assert word in text


def test_validator_keys_come_from_the_schema():
    assert set(SECTIONS) == {s.name for s in SCHEMA}
    for s in SCHEMA:
        assert SECTIONS[s.name] == {k.name for k in s.keys}


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_template_runs_as_printed(tmp_path, capsys, dim):
    assert main(["template", "--dim", str(dim)]) == 0
    text = capsys.readouterr().out
    case = tmp_path / "case.toml"
    case.write_text(text)
    assert load_case(case).problem.mesh.dim == dim
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["status"] == "finished" and s["impacts"] >= 1
    assert text.count("#") >= 10  # every key is commented


@pytest.mark.parametrize("flag", [["--n", "4"], ["--set", "gap=0.1"]])
def test_benchmark_only_options_are_errors_with_a_case_file(tmp_path, capsys, flag):
    main(["template", "--dim", "1"])
    case = tmp_path / "case.toml"
    case.write_text(capsys.readouterr().out)
    assert main(["run", str(case), *flag, "--out", str(tmp_path / "o")]) == 2
    assert "does not apply to a case file" in capsys.readouterr().err
