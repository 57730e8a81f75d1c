"""The docs checker (make docs-check) reads what the docs show: fenced blocks, commands with their
expected exit status, and a Python example's printed output matched line by line."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
import check_commands as C  # noqa: E402


def test_blocks_commands_and_expected_status(tmp_path):
    md = tmp_path / "x.md"
    md.write_text("text\n```\nuvisi event a \\\n    --out b   # exit 1: a verdict\nuvisi replay: error: x\n"
                  "make demo\n```\n```python\nprint(1)\n```\n```\n1\n```\n")
    bl = C.blocks(md)
    assert [b[0] for b in bl] == ["", "python", ""]
    assert C.commands(bl[0][1]) == [("uvisi event a --out b", 1), ("make demo", 0)]


def test_expected_output_lines_in_order_with_prefix_lines():
    printed = "a 1\nnoise\nb 22 and more\nc\n"
    assert C.expected_output_found(["a 1", "b 22 ...", "c"], printed) is None
    assert C.expected_output_found(["c", "a 1"], printed) == "a 1"          # order matters
    assert C.expected_output_found(["b 23 ..."], printed) == "b 23 ..."


def test_file_commands_are_run_beside_uvisi(tmp_path):
    md = tmp_path / "x.md"
    md.write_text("```\nmkdir -p scratch\ncp a.toml scratch/b.toml\n"
                  "sed -i 's/^alpha = 2.0/alpha = 3.0/' scratch/b.toml\nuvisi budget --sequence scratch/b.toml\n"
                  "ls scratch\n```\n")
    cmds = C.commands(C.blocks(md)[0][1])
    assert [c for c, _ in cmds] == ["mkdir -p scratch", "cp a.toml scratch/b.toml",
                                    "sed -i 's/^alpha = 2.0/alpha = 3.0/' scratch/b.toml",
                                    "uvisi budget --sequence scratch/b.toml"]   # ls: not a command run


def test_each_command_run_says_its_wall_and_cpu_time(tmp_path):
    import re
    res, cost = C.timed([sys.executable, "-c", "sum(range(10**6))"], tmp_path, 60)
    assert res.returncode == 0
    assert re.fullmatch(r"\d+\.\d s wall, \d+\.\d s CPU, load \d+\.\d", cost), cost


def test_one_document_by_name(capsys):
    assert C.main(["--list", "README.md"]) == 0
    out = capsys.readouterr().out
    assert out and all(line.startswith("README.md:") for line in out.splitlines())
    assert C.main(["--list", "docs/api.md"]) == 0
    assert all(line.startswith("docs/api.md:") for line in capsys.readouterr().out.splitlines())


def test_readme_is_a_manual_of_at_most_450_lines():
    text = C.ROOT.joinpath("README.md").read_text()
    assert len(text.splitlines()) <= 450
    # the glossary comes before the first job, and every job has a command block the checker runs
    assert text.index("## Glossary") < text.index("## Job 1")
    for job in ("## Job 1", "## Job 2", "## Job 3", "## Job 4"):
        section = text[text.index(job):].split("\n## ", 1)[0]
        assert "\n```\nmkdir -p scratch\nuvisi " in section or "\nuvisi " in section, job


#: the documents whose examples run in seconds: make test runs them as written (make docs-check
#: adds README.md and docs/validation.md, minutes, on CI)
FAST_DOCS = ("api.md", "budget.md", "cli.md", "design.md", "fidelity.md", "formats.md")


def test_the_fast_documents_run_as_written(capsys):
    """Every command and Python example of the fast documents runs and prints what they show."""
    fails = []
    for name in FAST_DOCS:
        fails += C.check(C.ROOT / "docs" / name, timeout=600, dry=False)
    capsys.readouterr()
    assert fails == [], "\n".join(fails)


def test_the_record_example_in_formats_is_a_record():
    """docs/formats.md's record example parses as a record, and its comment lists the features
    by their names in flightsw.messages.FEATURE_NAMES' order."""
    import re

    from flightsw.messages import FEATURE_NAMES
    from flightsw.records import Record
    text = C.ROOT.joinpath("docs", "formats.md").read_text()
    block = next(lines for lang, lines, _ in C.blocks(C.ROOT / "docs" / "formats.md")
                 if lang == "toml" and "[record]" in lines)
    body = "\n".join(block)
    listed = re.findall(r"#\s*(.*)", body[body.index("[feature.size]"):])
    names = [n.split("(")[0].strip() for ln in listed for n in ln.split(",") if n.strip()]
    start = names.index("size")
    assert names[start:start + len(FEATURE_NAMES)] == list(FEATURE_NAMES), names
    # the example with the other eleven features filled in as it shows the first is a record
    feat = body[body.index("[feature.size]"):]
    one = "\n".join(ln.split("#")[0].rstrip() for ln in feat.splitlines()[1:])
    full = body[:body.index("[feature.size]")] + "".join(
        f"\n[feature.{n}]\n{one}\n" for n in FEATURE_NAMES)
    rec = Record.from_toml(full)
    assert rec.name == "aurora" and len(rec.mean) == len(FEATURE_NAMES)
    assert "sigma > 0" in text
