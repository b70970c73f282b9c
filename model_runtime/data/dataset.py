"""Many clips: discovery, a versioned on-disk cache, the subject split and training windows."""

import csv
import dataclasses
import functools
import hashlib
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from ..skeleton import NUM_JOINTS
from . import bvh, clips, profiles

CACHE_VERSION = 3  # bump whenever clips.load_clip's output changes
_SHARED = Path(__file__).resolve().parents[3] / "shared"
# The shared CMU/ACCAD folders beside the repository (each with its MANIFEST.csv), unless
# $TRAJEVAE_MOCAP lists others (separated by the path separator).
DATA_ROOTS = tuple(Path(root) for root in os.environ["TRAJEVAE_MOCAP"].split(os.pathsep)) \
    if os.environ.get("TRAJEVAE_MOCAP") else (_SHARED / "mocap", _SHARED / "mocap-extra")
# Whole subjects held out for validation, one per kind of motion: everyday (CMU 02: walks,
# a jump, bending, swordplay, washing), locomotion (CMU 08: walks and strides) and sport
# (ACCAD Male2: martial arts). No window of theirs is trained on.
VALIDATION_SUBJECTS = ("CMU 02", "CMU 08", "ACCAD Male2")
WINDOW_FUTURE = 60  # 2 s at clips.NATIVE_FPS


def cache_dir():
    """Where loaded clips are kept: $TRAJEVAE_CACHE, else ~/.cache/trajevae."""
    root = os.environ.get("TRAJEVAE_CACHE") or Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "trajevae"
    return Path(root) / f"motion-v{CACHE_VERSION}-{clips.NATIVE_FPS}fps"


def find_bvh(paths):
    """BVH files among files and folders (searched recursively), sorted, no duplicates."""
    found = set()
    for path in map(Path, paths):
        if path.is_dir():
            found.update(p.resolve() for p in path.rglob("*") if p.suffix.lower() == ".bvh")
        else:
            found.add(path.resolve())
    return sorted(found)


def read_manifest(roots=DATA_ROOTS):
    """Rows of the roots' MANIFEST.csv files keyed by resolved file path (a root without one adds none)."""
    rows = {}
    for root in map(Path, roots):
        if (root / "MANIFEST.csv").exists():
            with open(root / "MANIFEST.csv", newline="") as handle:
                rows.update({(root / row["file"]).resolve(): row for row in csv.DictReader(handle)})
    return rows


_STORED_FIELDS = [f.name for f in dataclasses.fields(clips.Clip) if f.name != "file"]


def _from_array(value):
    """A cached field back to its Python type (0-d arrays to scalars)."""
    return value.item() if value.ndim == 0 else value


def _cache_path(path, custom=()):
    """The cache file of one BVH file as mapped with ``custom`` profiles (a mapping file changes
    the clip, so it is part of the key)."""
    stat = path.stat()
    key = f"{path}|{stat.st_size}|{stat.st_mtime_ns}" + "".join(f"|{profile}" for profile in custom)
    return cache_dir() / (hashlib.sha1(key.encode()).hexdigest() + ".npz")


def _load_cached(path, custom=()):
    """One clip from the cache, or loaded and cached; an error string if it cannot be read or mapped."""
    path = Path(path)
    cached = _cache_path(path, custom)
    if cached.exists():
        with np.load(cached) as stored:
            return clips.Clip(file=str(path), **{name: _from_array(stored[name]) for name in _STORED_FIELDS})
    try:
        clip = clips.load_clip(path, custom)
    except (bvh.BVHError, profiles.MappingError, OSError) as error:
        return str(error)
    cached.parent.mkdir(parents=True, exist_ok=True)
    temporary = cached.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez(temporary, **{name: getattr(clip, name) for name in _STORED_FIELDS})
    temporary.replace(cached)
    return clip


def load_clips(paths, workers=None, progress=None, custom=()):
    """Load every BVH under ``paths``. Returns (clips, errors): errors are one line per bad file.

    Uncached files are read in ``workers`` processes (default: all cores).
    ``progress(done, total)`` is called as files finish. ``custom`` profiles (from mapping files)
    are tried before the built-in ones.
    """
    files = find_bvh(paths)
    uncached = [f for f in files if not _cache_path(f, custom).exists()]
    workers = workers or os.cpu_count() or 1
    load = functools.partial(_load_cached, custom=tuple(custom))
    if len(uncached) > 1 and workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            for done, _ in enumerate(pool.map(load, uncached, chunksize=1), 1):
                if progress:
                    progress(done, len(files))
    loaded, errors = [], []
    for result in map(load, files):
        (errors if isinstance(result, str) else loaded).append(result)
    if progress:
        progress(len(files), len(files))
    return loaded, errors


def split_by_subject(clip_list, manifest, validation_subjects=VALIDATION_SUBJECTS):
    """(train, validation) clips; a file outside the manifest is a training clip."""
    train, validation = [], []
    for clip in clip_list:
        row = manifest.get(Path(clip.file).resolve())
        (validation if row and row["subject"] in validation_subjects else train).append(clip)
    return train, validation


@dataclasses.dataclass
class Split:
    """Training and validation clips, with how they were chosen (for the weights' meta and card)."""

    train: list
    validation: list
    errors: list
    validation_rule: str
    paths: list

    def describe(self):
        minutes = lambda part: round(sum(clip.seconds for clip in part) / 60, 1)
        return {"paths": [str(path) for path in self.paths], "train_clips": len(self.train),
                "train_minutes": minutes(self.train), "validation_clips": len(self.validation),
                "validation_minutes": minutes(self.validation), "validation": self.validation_rule}


HELD_OUT_EVERY = 10  # without validation subjects or files, every tenth file (sorted) is held out


def training_split(data=DATA_ROOTS, validation=None, custom=()):
    """A ``Split`` of the BVH files under ``data``: the files under ``validation`` if given, else
    the manifests' ``VALIDATION_SUBJECTS``, else every ``HELD_OUT_EVERY``-th file."""
    loaded, errors = load_clips(list(data) + list(validation or []), custom=custom)
    paths = list(data) + list(validation or [])
    if validation:
        held = set(find_bvh(validation))
        train = [clip for clip in loaded if Path(clip.file).resolve() not in held]
        return Split(train, [clip for clip in loaded if Path(clip.file).resolve() in held], errors,
                     "files under " + ", ".join(map(str, validation)), paths)
    train, held = split_by_subject(loaded, read_manifest(data))
    if held:
        return Split(train, held, errors, "subjects " + ", ".join(VALIDATION_SUBJECTS), paths)
    every = HELD_OUT_EVERY
    return Split([c for i, c in enumerate(loaded) if i % every != every - 1], loaded[every - 1::every], errors,
                 f"every {every}th file", paths)


def add_data_arguments(parser):
    """The training and evaluation commands' --data, --validation and --mapping options."""
    parser.add_argument("--data", nargs="+", default=[str(root) for root in DATA_ROOTS],
                        help="BVH files or folders (default: ../shared/mocap and ../shared/mocap-extra)")
    parser.add_argument("--validation", nargs="+", help="BVH files or folders held out for validation "
                        f"(default: the subjects {', '.join(VALIDATION_SUBJECTS)}, else every {HELD_OUT_EVERY}th file)")
    parser.add_argument("--mapping", nargs="+", default=[],
                        help="JSON files mapping the 14 joints to a library's bone names (docs/mapping-example.json)")


def mapping_profiles(parser, paths):
    """The profiles of the mapping files ``paths`` (--mapping); a bad one is a parser error."""
    try:
        return tuple(profiles.read_mapping(path) for path in paths)
    except ValueError as error:
        parser.error(str(error))


def split_from_arguments(parser, args):
    """The ``Split`` that ``add_data_arguments``' options ask for; a bad mapping file or no usable
    clip is a parser error (one sentence)."""
    split = training_split(args.data, args.validation, mapping_profiles(parser, args.mapping))
    for error in split.errors:
        print(f"skipped: {error}", file=sys.stderr)
    if not split.train or not split.validation:
        parser.error(f"{len(split.train)} training and {len(split.validation)} validation clips could be read "
                     f"from {' '.join(map(str, split.paths))}: both are needed")
    return split


def windows(clip_list, future=WINDOW_FUTURE, stride=5):
    """Training windows (N, 1 + future, 17, 3): an initial pose then ``future`` frames.

    Each window is moved so its initial root (Hip) sits at the origin of the
    ground plane; heights above the floor are kept. Facing is left as
    captured (training rotates about Z at random).
    """
    length = 1 + future
    parts = []
    for clip in clip_list:
        if clip.frames < length:
            continue
        starts = np.arange(0, clip.frames - length + 1, stride)
        index = starts[:, None] + np.arange(length)[None, :]
        parts.append(normalise(clip.positions[index]))
    if not parts:
        return np.zeros((0, length, NUM_JOINTS, 3), dtype=np.float32)
    return np.concatenate(parts).astype(np.float32)


def normalise(window):
    """Windows (..., T, 17, 3) with the first frame's root moved to x = y = 0."""
    shift = np.zeros_like(window[..., :1, :1, :])
    shift[..., 0] = window[..., :1, :1, 0]
    shift[..., 1] = window[..., :1, :1, 1]
    return window - shift
