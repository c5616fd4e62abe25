"""The docs say what the code does: the generated parts are up to date, the option table is the flags of
``bitemesh mesh --help``, every link leads to a file, the README is a page and its Python is the public API."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import bitemesh
from bitemesh import cli

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))
import generate  # noqa: E402


def test_the_generated_docs_are_up_to_date():
    stale = [str(path) for path, text in generate.expected().items() if path.read_text() != text]
    assert not stale, f"run python docs/generate.py: {stale}"


def test_the_option_table_holds_every_flag_of_mesh_help(capsys):
    try:
        cli.main(["mesh", "--help"])
    except SystemExit:
        pass
    help_flags = set(re.findall(r"(--[a-z][a-z-]+)", capsys.readouterr().out))
    help_flags -= {"--help", "--output"} | {flag for flag in help_flags if flag.startswith("--no-")}
    table = generate.option_table()
    table_flags = set(re.findall(r"^\| `(--[a-z-]+)`", table, re.M))
    assert help_flags == table_flags, help_flags ^ table_flags


def links(path: Path) -> list:
    """The relative links of a markdown file (no web address, no anchor alone)."""
    found = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", path.read_text())
    return [link for link in found if not link.startswith(("http://", "https://", "mailto:"))]


def test_every_link_of_the_readme_and_the_docs_leads_to_a_file():
    broken = [f"{path.relative_to(ROOT)}: {link}" for path in [ROOT / "README.md", *DOCS.glob("*.md")]
              for link in links(path) if not (path.parent / link).exists()]
    assert not broken, broken


def test_the_readme_is_a_page_that_links_every_doc():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 180
    linked = {Path(link).name for link in links(ROOT / "README.md")}
    assert {path.name for path in DOCS.glob("*.md")} <= linked


def test_the_readme_shows_the_public_api():
    """Every ``bitemesh.<name>`` of the README's code is a public name of the package, and it runs: the front
    door on arrays, with an option as a keyword."""
    readme = (ROOT / "README.md").read_text()
    code = "\n".join(re.findall(r"```python\n(.*?)```", readme, re.S))
    used = set(re.findall(r"\bbitemesh\.([A-Za-z_]\w*)", code))
    assert used and used <= set(bitemesh.__all__), used - set(bitemesh.__all__)


def test_the_two_commands_lead_the_readme():
    first = (ROOT / "README.md").read_text().split("```")[1]
    assert "pip install . && bitemesh demo" in first and 'pip install ".[test]" && python -m pytest' in first
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install ".[test]" && python -m pytest' in ci


def test_generate_check_exits_0_when_up_to_date():
    assert subprocess.run([sys.executable, str(DOCS / "generate.py"), "--check"]).returncode == 0
