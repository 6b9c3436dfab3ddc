"""Publish a study's JSON summary to the documentation's validation pages.

Studies write to ``studies/output/`` (not in the repository). The validation pages
(``docs/validation/``) are built from the summaries copied to ``docs/validation/data/``,
which are committed, so the pages build on a clean clone. This script copies one, with
where it came from: the command that produced it (give it; the studies do not record
their own command line), the date and the commit.

Usage::

    python studies/recovery.py --n 40 --max-steps 20000 --workers 1 --truth prior \\
        --priors studies/calibration_priors.toml --tag _docs_calibration
    python studies/publish.py calibration --tag _docs_calibration --command \\
        "python studies/recovery.py --n 40 ... --tag _docs_calibration"

Keys (:data:`SOURCES`): each names a page section; ``--tag`` fills the study's tag.
"""

import argparse
import datetime
import json
import subprocess
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUTPUT = HERE / "output"
DATA = HERE.parent / "docs" / "validation" / "data"

#: Published key → the study's summary under studies/output ({tag}: the run's tag).
SOURCES = {
    "forward-accuracy": "forward_runtime_vs_error/summary.json",
    "expected-model-accuracy": "stand_model_runtime_vs_error/summary.json",
    "inversion-speed": "inversion_speed{tag}/summary.json",
    "inversion-speed-real": "inversion_speed{tag}/summary.json",
    "sampling-coordinates-real": "sampling_coordinates{tag}/references.json",
    "preparation-spread": "preparation_spread{tag}/summary.json",
    "continuity": "continuity{tag}/summary.json",
    "calibration": "recovery{tag}/summary.json",
    "calibration-out-of-family": "recovery{tag}/summary.json",
    "recovery": "recovery{tag}/summary.json",
    "batch-throughput": "batch_throughput.json",
    "scaling": "scaling/scaling.json",
    "real-products": "real_products{tag}/summary.json",
    "real-inversion": "real_inversion{tag}/summary.json",
    "real-inversion-shared": "real_inversion{tag}/summary.json",
    "real-inversion-tall": "real_inversion{tag}/summary.json",
}


def _commit() -> str:
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=HERE,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def publish(key: str, command: str, tag: str = "", data=DATA) -> Path:
    """Copy the summary of ``key`` into ``data/<key>.json`` with its provenance."""
    if key not in SOURCES:
        raise SystemExit(f"unknown key {key!r}; known: {sorted(SOURCES)}")
    source = OUTPUT / SOURCES[key].format(tag=tag)
    if not source.exists():
        raise SystemExit(f"no summary at {source}: run the study first")
    record = {
        "key": key,
        "source": str(source.relative_to(HERE.parent)),
        "command": command,
        "published": datetime.date.today().isoformat(),
        "commit": _commit(),
        "summary": json.loads(source.read_text()),
    }
    data = Path(data)
    data.mkdir(parents=True, exist_ok=True)
    path = data / f"{key}.json"
    path.write_text(json.dumps(record, indent=1) + "\n")
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("key", choices=sorted(SOURCES))
    parser.add_argument("--tag", default="", help="the study run's --tag")
    parser.add_argument("--command", required=True, help="the command that ran the study")
    args = parser.parse_args()
    print(f"wrote {publish(args.key, args.command, args.tag)}")


if __name__ == "__main__":
    main()
