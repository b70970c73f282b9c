"""Training data for a GPU machine that has no ../shared beside it (the workplace's device tool
sends the repository alone, 64 MiB at most).

Here, after the clips have loaded once (any training, test or ``make bench-data``)::

    .venv/bin/python scripts/device_data.py pack

puts the loaded clips of ../shared's BVH files (about 23 MB) and the folders' MANIFEST.csv files
under .gpu/ (ignored by git). There, first in the command, with ``.gpu`` carried::

    python3 scripts/device_data.py unpack
    export TRAJEVAE_CACHE=$PWD/.gpu/cachedir TRAJEVAE_MOCAP=$PWD/.gpu/data/mocap:$PWD/.gpu/data/mocap-extra
    python3 -m model_runtime.train ...

``unpack`` makes an empty file where each BVH file was and files its loaded clip under the cache
key that empty file gets there (the key holds the path, size and time), so the loader finds every
clip cached and the manifests give the same subjects and split.
"""

import json
import os
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from model_runtime.data import dataset  # noqa: E402

PACKED = ROOT / ".gpu"
CLIPS = "clips.json"  # BVH path under its folder's parent -> the packed clip's file name


def pack():
    """The loaded clips and manifests of ``dataset.DATA_ROOTS`` into PACKED."""
    (PACKED / "cache").mkdir(parents=True, exist_ok=True)
    clips, missing = {}, 0
    for root in dataset.DATA_ROOTS:
        (PACKED / "data" / root.name).mkdir(parents=True, exist_ok=True)
        shutil.copy(root / "MANIFEST.csv", PACKED / "data" / root.name / "MANIFEST.csv")
        for path in dataset.find_bvh([root]):
            cached = dataset._cache_path(path)
            if not cached.exists():
                missing += 1
                continue
            shutil.copy(cached, PACKED / "cache" / cached.name)
            clips[f"{root.name}/{path.relative_to(root.resolve()).as_posix()}"] = cached.name
    (PACKED / CLIPS).write_text(json.dumps(clips))
    print(f"packed {len(clips)} clips into {PACKED}" + (f"; {missing} not loaded yet (load them first)" if missing else ""))


def unpack():
    """Empty BVH files under PACKED/data and the packed clips filed under the keys they get here."""
    os.environ["TRAJEVAE_CACHE"] = str(PACKED / "cachedir")
    for relative, name in json.loads((PACKED / CLIPS).read_text()).items():
        path = PACKED / "data" / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.touch()
        key = dataset._cache_path(path.resolve())
        key.parent.mkdir(parents=True, exist_ok=True)
        if not key.exists():
            os.symlink(PACKED / "cache" / name, key)
    print(f"unpacked into {PACKED / 'data'}; TRAJEVAE_CACHE={PACKED / 'cachedir'}")


if __name__ == "__main__":
    commands = {"pack": pack, "unpack": unpack}
    if len(sys.argv) != 2 or sys.argv[1] not in commands:
        sys.exit(f"usage: {Path(__file__).name} pack|unpack")
    commands[sys.argv[1]]()
