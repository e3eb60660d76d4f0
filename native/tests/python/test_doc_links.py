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


def test_a_section_cited_from_the_code_must_exist(tmp_path):
    # Code comments cite sections by heading, as docs/<topic>.md "Heading" (a name may run on over
    # comment lines, and a heading may go on past it); a renamed or moved section leaves the name
    # dangling, and the check names the file and line.
    (tmp_path / "docs" / "history").mkdir(parents=True)
    (tmp_path / "README.md").write_text("# R\n")
    (tmp_path / "docs" / "a.md").write_text("# A\n## The two directions today\n### Options (`x.h`)\n")
    (tmp_path / "docs" / "history" / "a.md").write_text("# H\n## Session 23: both directions agree\n")
    a, h = "docs" + "/a.md", "docs" + "/history/a.md"   # (split: this file is checked too)
    (tmp_path / "native").mkdir()
    (tmp_path / "native" / "ok.cpp").write_text(
        f'// ({a} "The two directions\n// today"; {a}, "Options"; {h} "Session 23")\n'
        f'auto s = "see {a} \\"Options\\"";\n')
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "check_doc_links.py"), str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stdout
    assert "4 sections cited from code, 0 from the docs, 0 bad" in run.stdout, run.stdout
    (tmp_path / "native" / "bad.py").write_text(
        f'"""x"""\n# first line\n# ({a} "Session 23" and "Options"; {h}\n# "Session 24")\n')
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "check_doc_links.py"), str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 1
    assert f'SECTION native/bad.py:3 {a} "Session 23"' in run.stdout, run.stdout
    assert f'SECTION native/bad.py:3 {h} "Session 24"' in run.stdout, run.stdout
    assert "2 bad" in run.stdout and '"Options"' not in run.stdout.replace('"Session', '')


def test_a_section_cited_from_another_doc_must_exist(tmp_path):
    # The docs cite each other's sections the same way, as [a.md](a.md) "Heading" or a.md "Heading";
    # the logs in docs/history/ keep the names they were written with and are not checked.
    (tmp_path / "docs" / "history").mkdir(parents=True)
    (tmp_path / "README.md").write_text('See [docs/a.md](docs/a.md), "Known\nlimits".\n')
    (tmp_path / "docs" / "a.md").write_text("# A\n## Known limits\n")
    (tmp_path / "docs" / "b.md").write_text('# B\n[a.md](a.md) "Known limits"; a.md "Session 26"\n')
    (tmp_path / "docs" / "history" / "b.md").write_text('# Log\nas a.md "Session 26" said\n')
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "check_doc_links.py"), str(tmp_path)],
                         capture_output=True, text=True)
    assert run.returncode == 1
    assert 'SECTION docs/b.md:2 a.md "Session 26"' in run.stdout, run.stdout
    assert "3 from the docs, 1 bad" in run.stdout, run.stdout
