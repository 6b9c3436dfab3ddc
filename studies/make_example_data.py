"""Cut the example files shipped in ``lidarinv/data`` from the real development files.

Every sixth shot of each GEDI beam and every eighth LVIS shot, with their L2A, L2B and
LVIS L2 rows, in the products' own layouts (the readers and ``lidarinv metrics`` treat
them as the originals). The shots are taken by position, not by content.

    python studies/make_example_data.py [--source ../shared/data/real] [--out lidarinv/data]
"""

import argparse
import shutil
from pathlib import Path

import h5py
import numpy as np

GEDI_STEP, LVIS_STEP = 6, 8
NAMES = {
    "GEDI01_B_2019108080338_O01964_T05337_02_003_01_sub.h5": "gedi-l1b",
    "GEDI02_A_2019108080338_O01964_T05337_02_001_01_sub.h5": "gedi-l2a",
    "GEDI02_B_2019108080338_O01964_T05337_02_001_01_sub.h5": "gedi-l2b",
    "LVIS1B_Gabon2016_Mondah_clip.h5": "lvis-l1b",
    "LVIS2_Gabon2016_Mondah_clip.txt": "lvis-l2",
}


def _copy_attrs(source, target):
    for key, value in source.attrs.items():
        target.attrs[key] = value


def _subset_group(source, target, keep, n_shots):
    """Copy a group, keeping the rows ``keep`` of every per-shot dataset."""
    _copy_attrs(source, target)
    for name, item in source.items():
        if isinstance(item, h5py.Group):
            _subset_group(item, target.create_group(name), keep, n_shots)
            continue
        data = item[()]
        if data.ndim >= 1 and data.shape[0] == n_shots:
            data = data[keep]
        elif data.ndim == 2 and data.shape[1] == n_shots:
            data = data[:, keep]
        target.create_dataset(name, data=data, compression="gzip" if data.size > 4096 else None)


def _gedi_l1b_beam(source, target, keep):
    """A GEDI L1B beam with its concatenated waveforms re-indexed to the kept shots."""
    n = source["shot_number"].shape[0]
    concatenated = {"rxwaveform": "rx", "txwaveform": "tx"}
    skip = set(concatenated) | {f"{p}_sample_start_index" for p in concatenated.values()}
    _copy_attrs(source, target)
    for name, item in source.items():
        if name in skip:
            continue
        if isinstance(item, h5py.Group):
            _subset_group(item, target.create_group(name), keep, n)
        else:
            data = item[()]
            target.create_dataset(name, data=data[keep] if data.shape[0] == n else data)
    for wave, prefix in concatenated.items():
        start = source[f"{prefix}_sample_start_index"][()].astype(np.int64) - 1
        count = source[f"{prefix}_sample_count"][()].astype(np.int64)
        values = source[wave][()]
        pieces = [values[start[i] : start[i] + count[i]] for i in keep]
        new_start = np.concatenate([[0], np.cumsum([p.size for p in pieces])[:-1]]) + 1
        target.create_dataset(wave, data=np.concatenate(pieces), compression="gzip")
        dtype = source[f"{prefix}_sample_start_index"].dtype
        target.create_dataset(f"{prefix}_sample_start_index", data=new_start.astype(dtype))


def make(source: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    files = {name: source / original for original, name in NAMES.items()}
    for name in ("gedi-l1b", "gedi-l2a", "gedi-l2b"):
        with (
            h5py.File(files[name], "r") as src,
            h5py.File(out / f"{name}.h5", "w", libver="latest") as dst,
        ):
            _copy_attrs(src, dst)
            for beam in sorted(k for k in src if k.startswith("BEAM")):
                n = src[beam]["shot_number"].shape[0]
                keep = np.arange(0, n, GEDI_STEP)
                if name == "gedi-l1b":
                    _gedi_l1b_beam(src[beam], dst.create_group(beam), keep)
                else:
                    _subset_group(src[beam], dst.create_group(beam), keep, n)
    with (
        h5py.File(files["lvis-l1b"], "r") as src,
        h5py.File(out / "lvis-l1b.h5", "w", libver="latest") as dst,
    ):
        n = src["RXWAVE"].shape[0]
        keep = np.arange(0, n, LVIS_STEP)
        _subset_group(src, dst, keep, n)
        kept_shots = set(src["SHOTNUMBER"][()][keep].astype(np.int64))
    lines = files["lvis-l2"].read_text().splitlines()
    rows = [line for line in lines if line.split() and int(float(line.split()[1])) in kept_shots]
    (out / "lvis-l2.txt").write_text("\n".join(rows) + "\n")
    readme = source / "README.md"
    if readme.exists():
        shutil.copy(readme, out / "README.md")


def main(argv=None) -> None:
    here = Path(__file__).resolve().parent.parent
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, default=here.parent / "shared" / "data" / "real")
    parser.add_argument("--out", type=Path, default=here / "lidarinv" / "data")
    args = parser.parse_args(argv)
    make(args.source, args.out)
    for path in sorted(args.out.iterdir()):
        print(f"{path}  {path.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
