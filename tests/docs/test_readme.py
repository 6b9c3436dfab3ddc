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
