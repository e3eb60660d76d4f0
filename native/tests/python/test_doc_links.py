"""The documentation's relative links and anchors resolve (scripts/check_doc_links.py), and no
link in README.md or docs/ leads outside the repository."""
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[3]


def test_every_relative_link_in_the_docs_resolves():
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "check_doc_links.py"), str(REPO)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert " 0 bad" in run.stdout


def test_a_broken_link_is_reported(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("[ok](docs/a.md#title) [gone](docs/b.md) [far](https://example.org)\n")
    (tmp_path / "docs" / "a.md").write_text("# Title\n[bad anchor](#nowhere)\n")
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "check_doc_links.py"), str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 1
    assert "MISSING" in run.stdout and "docs/b.md" in run.stdout
    assert "ANCHOR" in run.stdout and "#nowhere" in run.stdout
    assert "EXTERNAL" in run.stdout
    assert "3 bad" in run.stdout
