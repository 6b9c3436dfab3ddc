"""The README: short, its Python snippets run as written, and CI runs its test command."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def test_readme_is_short():
    assert len(README.splitlines()) <= 150


def test_ci_runs_exactly_the_readmes_test_command():
    commands = re.search(r"```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert len(commands) == 2  # install and run the demo; install and run the tests
    assert "lidarinv invert --example" in commands[0]
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1] == commands[1]


def test_readme_python_snippets_run(tmp_path, monkeypatch):
    snippets = re.findall(r"```python\n(.*?)```", README, re.S)
    assert snippets
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for code in snippets:  # in order, in one namespace, as a reader would
        exec(compile(code, "README.md", "exec"), namespace)


def test_getting_started_quotes_the_lines_the_demo_prints_without_stale_numbers():
    """The demo's first lines as ``lidarinv invert`` writes them (labels and meanings from
    the code), and no result numbers that a change of the code would leave stale: those
    the docs show are printed by the tutorials when the docs build."""
    from lidarinv.cli.invert import HEADLINE

    page = (ROOT / "docs" / "getting-started.rst").read_text()
    block = page.split("shot gedi-mixed: the footprint (median, 90 % interval)\n")[1]
    quoted = re.findall(r"^      (\S.*?)\s+MEDIAN(?: m)?\s+\[P05, P95\]  (.*)$", block, re.M)
    known = {(label, meaning) for _, label, meaning in HEADLINE}
    stand = ("stand top_height", "upper limit of the stand's height distribution "
             "(mean + 2 sd), which one footprint rarely reaches")  # fmt: skip
    assert len(quoted) >= 5 and set(quoted) <= known | {stand}
    interval = re.compile(r"\d\.?\d*\s*\[\d+\.?\d*, \d+\.?\d*\]")  # "0.338 [0.175, 0.547]"
    prose = [README, page]
    prose += [p.read_text() for p in (ROOT / "docs" / "tutorials").glob("*.py")]
    for text in prose:
        assert not interval.search(text), interval.search(text).group()
