"""Build the installable Blender extension: ``dist/photic-<version>-linux_x64.zip``.

    .venv/bin/python scripts/build_extension.py [--out dist] [--wheel-cache .cache/wheels]

Steps:

1. the engine's wheel is built from ``engine/`` (``pip wheel --no-build-isolation``, so the
   running environment must hold scikit-build-core, pybind11 and CMake, as ``scripts/install.sh``
   sets up); its compiled core needs only the C++ runtime: it loads the Embree 4 library of
   the bundled embreex wheel (with that wheel's TBB) when imported, so the machine running
   Blender needs no Embree or TBB of its own (tests/test_extension.py hides the system's). The
   wheel is tagged ``linux_x86_64`` (built here, not audited for manylinux);
2. the wheels the engine needs beyond Blender's own numpy are downloaded (binary only, for this
   interpreter's CPython version on manylinux x86_64, no dependency resolution: the list below is
   complete). Versions are pinned to those installed here, the combination the tests ran with;
   ``--wheel-cache`` keeps them, and a cache that already holds them all needs no network;
3. ``blender_addon/`` is staged with the wheels under ``wheels/``, the manifest's ``wheels``
   list rewritten to name them, and the whole zipped with the manifest at the zip's root.

Run it with the Python of the Blender it targets (3.11 for Blender 4.2 to 5.0): the engine's
wheel is built for the running interpreter and the other wheels are chosen for its version.
Install the zip with Edit > Preferences > Get Extensions > Install from Disk, or headless::

    bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default",
                                             enable_on_install=True)
"""
from __future__ import annotations

import argparse
import fcntl
import importlib.metadata
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ADDON = ROOT / "blender_addon"
ENGINE = ROOT / "engine"
# Everything the engine needs beyond the standard library and numpy (which Blender bundles).
# embreex carries the Embree 4 library (and its TBB) that the engine's core loads.
DEPENDENCIES = ["embreex", "trimesh", "OpenEXR", "jsonschema", "attrs", "referencing",
                "rpds-py", "jsonschema-specifications", "typing-extensions"]
PLATFORMS = ["manylinux2014_x86_64"] + [f"manylinux_2_{m}_x86_64" for m in range(17, 29)]
EXCLUDE_DIRS = {"__pycache__", "photic_blender.egg-info"}
EXCLUDE_FILES = {"README.md", "site_packages.txt", "pyproject.toml"}  # (the pip package's file)


def _pip(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "pip", *args], check=True)


def _pinned(name: str) -> str:
    try:
        return f"{name}=={importlib.metadata.version(name)}"
    except importlib.metadata.PackageNotFoundError:
        return name


def build_engine_wheel(dest: Path, build_dir: Path) -> Path:
    """The engine's wheel, built from source into ``dest`` (CMake files kept in ``build_dir``)."""
    _pip("wheel", "--no-deps", "--no-build-isolation", "-q", str(ENGINE), "-w", str(dest),
         "-C", f"build-dir={build_dir}")
    return next(dest.glob("photic-*.whl"))


def fetch_dependency_wheels(cache: Path) -> list[Path]:
    """The dependency wheels in ``cache``: taken from it when all there, else downloaded."""
    py = f"{sys.version_info.major}.{sys.version_info.minor}"
    abi = f"cp{sys.version_info.major}{sys.version_info.minor}"
    requirements = [_pinned(n) for n in DEPENDENCIES]
    common = ["download", "--only-binary=:all:", "--no-deps", "-q", "-d", str(cache),
              "--python-version", py, "--implementation", "cp", "--abi", abi, "--abi", "abi3",
              "--abi", "none", *[a for p in PLATFORMS for a in ("--platform", p)]]
    cache.mkdir(parents=True, exist_ok=True)
    try:  # offline first: the cache may hold everything already
        subprocess.run([sys.executable, "-m", "pip", *common, "--no-index", "--find-links",
                        str(cache), *requirements], check=True, capture_output=True)
    except subprocess.CalledProcessError:
        try:
            _pip(*common, *requirements)
        except subprocess.CalledProcessError as exc:
            raise SystemExit(f"downloading the dependency wheels failed (is the package index "
                             f"reachable?): {' '.join(requirements)}") from exc
    wheels = []
    for req in requirements:
        name, _, version = req.partition("==")
        stem = re.sub(r"[-_.]+", "_", name).lower()
        found = sorted(w for w in cache.glob("*.whl")
                       if w.name.lower().startswith(stem + "-")
                       and (not version or w.name.split("-")[1] == version))
        if not found:
            raise SystemExit(f"no wheel for {req} in {cache}")
        wheels.append(found[-1])
    return wheels


def stage_addon(stage: Path, wheels: list[Path]) -> dict:
    """Copy the add-on into ``stage`` with ``wheels`` under ``wheels/``; the manifest, parsed."""
    shutil.copytree(ADDON, stage, ignore=lambda d, names: [
        n for n in names if n in EXCLUDE_DIRS or (n in EXCLUDE_FILES and Path(d) == ADDON)])
    (stage / "wheels").mkdir()
    for w in wheels:
        shutil.copy2(w, stage / "wheels" / w.name)
    manifest_path = stage / "blender_manifest.toml"
    listing = "".join(f'\n  "./wheels/{w.name}",' for w in wheels)
    text, n = re.subn(r"(?ms)^wheels\s*=\s*\[.*?\]", f"wheels = [{listing}\n]",
                      manifest_path.read_text())
    if n != 1:
        raise SystemExit(f"{manifest_path}: expected one 'wheels = [...]' list")
    manifest_path.write_text(text)
    return tomllib.loads(text)


def build(out: Path, wheel_cache: Path | None = None) -> Path:
    out = out.resolve()
    work = ROOT / "build" / "extension"
    work.mkdir(parents=True, exist_ok=True)
    # One build at a time: concurrent runs (two test sessions) would share the CMake folder.
    with open(work / ".lock", "w") as lock, tempfile.TemporaryDirectory() as tmp:
        fcntl.flock(lock, fcntl.LOCK_EX)
        tmp = Path(tmp)
        engine_wheel = build_engine_wheel(tmp / "engine", work / "cmake")
        deps = fetch_dependency_wheels((wheel_cache or tmp / "wheels").resolve())
        stage = tmp / "stage"
        manifest = stage_addon(stage, [engine_wheel, *deps])
        out.mkdir(parents=True, exist_ok=True)
        platform = manifest["platforms"][0].replace("-", "_")
        zip_path = out / f"{manifest['id']}-{manifest['version']}-{platform}.zip"
        with zipfile.ZipFile(zip_path, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(stage.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(stage).as_posix())
    return zip_path


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "dist", help="output folder (dist/)")
    ap.add_argument("--wheel-cache", type=Path, default=None,
                    help="keep downloaded dependency wheels here and reuse them")
    args = ap.parse_args(argv)
    print(build(args.out, args.wheel_cache))


if __name__ == "__main__":
    main()
