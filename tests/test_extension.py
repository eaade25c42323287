"""The extension zip from ``scripts/build_extension.py``, installed into ``bpy`` and rendering.

The zip is built once per session; the dependency wheels are kept in ``.cache/wheels`` (git
ignores it), so only the first run downloads them (the package index must then be reachable:
the build fails with a clear message otherwise) and later builds take seconds.

Installing and rendering run in a child Python, as a fresh Blender would, isolated twice over:

- Blender's user folders (preferences, extensions and their wheels) point into ``tmp_path``
  through the ``BLENDER_USER_*`` variables that bpy 5.0 reads, so ``~/.config/blender`` is never
  touched and nothing is left installed;
- the child starts with ``python -I -S``: no site-packages, no ``.pth`` files, so neither the
  editable ``photic`` of this checkout (a ``.pth`` import hook plus a ``photic/_core*.so`` in the
  venv) nor the venv's trimesh/jsonschema/OpenEXR/embreex are visible. Its only addition to
  ``sys.path`` is a folder of links to what a Blender bundles (bpy itself, numpy, requests, ...),
  so every other import must come from the wheels the extension installed, and the test checks
  that they do.

A second run does the same with the system's Embree and TBB out of the loader's reach (a
private mount namespace in which /dev/null is bind-mounted over every libembree*/libtbb* file in
the system's library folders): the engine must find Embree in the extension's embreex wheel,
which carries its own TBB. It needs root (or CAP_SYS_ADMIN) for the namespace, and skips
without.
"""
from __future__ import annotations

import importlib.util
import json
import os
import shlex
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLEND = ROOT / "example_blends" / "canonical_problem2.blend"
# A water mesh: its closedness check (numpy) and the engine's Embree inside Blender's process;
# the bundled trimesh and embreex are imported at the end (mesh files, the bench baseline).
MESH_BLEND = ROOT / "example_blends" / "stepped_pool.blend"
WHEEL_CACHE = ROOT / ".cache" / "wheels"
# What Blender itself ships (bpy and its Python dependencies): the only modules, with the
# standard library, that the child may import besides the extension's wheels.
BLENDER_BUNDLED = ["bpy", "numpy", "numpy.libs", "requests", "certifi", "idna", "urllib3",
                   "charset_normalizer", "zstandard"]

CHILD = textwrap.dedent("""
    import importlib, importlib.util, json, sys
    blender_site, zip_path, blend, mesh_blend, out_dir = sys.argv[1:6]
    sys.path.append(blender_site)
    assert importlib.util.find_spec("photic") is None, "photic is importable before installing"

    import bpy
    ext_dir = bpy.utils.user_resource("EXTENSIONS")
    result = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    assert result == {"FINISHED"}, result
    assert hasattr(bpy.types.Scene, "photic"), "the add-on was not enabled on install"
    assert "bl_ext.user_default.photic" in bpy.context.preferences.addons, \\
        list(bpy.context.preferences.addons.keys())

    batch = importlib.import_module("bl_ext.user_default.photic.batch")
    summary = batch.render_blend(blend, out_dir=out_dir, samples=2, radiometer_samples=4096)
    meshes = batch.render_blend(mesh_blend, out_dir=out_dir, samples=1, radiometer_samples=256,
                                resolution_percentage=25)
    assert meshes["triangles"] > 0, meshes

    import photic, photic._core, trimesh, jsonschema, OpenEXR, embreex.rtcore_scene
    files = {m.__name__: m.__file__ for m in (photic, photic._core, trimesh, jsonschema,
                                              OpenEXR, embreex)}
    with open("/proc/self/maps") as maps:  # every Embree and TBB this process has mapped
        paths = {ln.split(maxsplit=5)[-1].strip() for ln in maps}
        mapped = sorted(f for f in paths if f.rsplit("/", 1)[-1].startswith(("libembree", "libtbb")))
    print("RESULT " + json.dumps({"ext_dir": ext_dir, "files": files,
                                  "image": summary["image"], "tables": summary["tables"],
                                  "mesh_image": meshes["image"], "embree": photic._core.EMBREE,
                                  "mapped": mapped}))
""")


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "build_extension.py"), "--out", str(out),
         "--wheel-cache", str(WHEEL_CACHE)], capture_output=True, text=True, timeout=900)
    if proc.returncode != 0:
        pytest.fail("building the extension failed (the first build downloads the dependency "
                    f"wheels into {WHEEL_CACHE}: is the package index reachable?)\n"
                    f"{proc.stdout[-3000:]}\n{proc.stderr[-6000:]}", pytrace=False)
    zip_path = Path(proc.stdout.strip().splitlines()[-1])
    assert zip_path.is_file() and zip_path.name == "photic-0.1.0-linux_x64.zip"
    return zip_path


# The system's libraries that the hidden run takes away, and a check that they are gone.
SYSTEM_LIB_DIRS = ["/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib", "/usr/local/lib"]
HIDDEN_PATTERNS = ["libembree*.so*", "libtbb*.so*"]
PROBE = textwrap.dedent("""
    import ctypes
    for name in ("libembree3.so.3", "libembree4.so.4", "libtbb.so.12"):
        try:
            ctypes.CDLL(name)
        except OSError:
            continue
        raise SystemExit(name + " is still loadable")
""")


def system_libraries() -> list[str]:
    found = {str(p.resolve()) for d in SYSTEM_LIB_DIRS for pat in HIDDEN_PATTERNS
             for p in Path(d).glob(pat)}
    return sorted(f for f in found if Path(f).is_file())


def hiding(files: list[str]) -> list[str]:
    """A command prefix running its command where ``files`` read as empty (a private mount
    namespace), after checking that the loader no longer finds Embree or TBB."""
    mounts = "".join(f"mount --bind /dev/null {shlex.quote(f)} && " for f in files)
    probe = f"{shlex.quote(sys.executable)} -I -S -c {shlex.quote(PROBE)}"
    return ["unshare", "--mount", "sh", "-c", f'{mounts}{probe} && exec "$@"', "sh"]


def install_and_render(extension_zip: Path, tmp_path: Path, prefix: list[str] = ()) -> dict:
    """The zip installed into a fresh Blender user folder by a child Python that then renders
    (the module docstring); its RESULT record, checked for where every import came from."""
    spec = importlib.util.find_spec("bpy")
    assert spec is not None, "bpy (Blender as a Python module) is not installed: run scripts/install.sh"
    site_packages = Path(spec.submodule_search_locations[0]).parent
    blender_site = tmp_path / "blender_site"
    blender_site.mkdir()
    for name in BLENDER_BUNDLED:
        if (site_packages / name).exists():
            (blender_site / name).symlink_to(site_packages / name)

    user = tmp_path / "blender_user"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_", "PHOTIC_"))}
    env.update(BLENDER_USER_RESOURCES=str(user), BLENDER_USER_CONFIG=str(user / "config"),
               BLENDER_USER_SCRIPTS=str(user / "scripts"),
               BLENDER_USER_EXTENSIONS=str(user / "extensions"),
               BLENDER_USER_DATAFILES=str(user / "datafiles"))
    out_dir = tmp_path / "out"
    proc = subprocess.run(
        [*prefix, sys.executable, "-I", "-S", "-c", CHILD, str(blender_site), str(extension_zip),
         str(BLEND), str(MESH_BLEND), str(out_dir)],
        env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert proc.returncode == 0 and lines, f"{proc.stdout[-4000:]}\n{proc.stderr[-6000:]}"
    result = json.loads(lines[-1][len("RESULT "):])

    # Everything beyond Blender's bundle came from the extension's wheels, none from this checkout.
    py = f"python{sys.version_info.major}.{sys.version_info.minor}"
    wheels_site = Path(result["ext_dir"]) / ".local" / "lib" / py / "site-packages"
    assert Path(result["ext_dir"]) == user / "extensions"
    for name, path in result["files"].items():
        assert Path(path).is_relative_to(wheels_site), (name, path)
        assert not Path(path).resolve().is_relative_to(ROOT), (name, path)
    # The engine traces with the Embree of the extension's embreex wheel.
    assert Path(result["embree"].split(" from ", 1)[1]).is_relative_to(wheels_site), result["embree"]

    assert Path(result["image"]).is_file() and Path(result["image"]).suffix == ".exr"
    assert Path(result["image"]).parent == out_dir
    assert Path(result["mesh_image"]).is_file()
    csv = [Path(p) for p in result["tables"] if p.endswith(".csv")]
    assert csv and csv[0].is_file() and csv[0].stat().st_size > 0
    return result


def test_extension_installs_and_renders(extension_zip, tmp_path):
    install_and_render(extension_zip, tmp_path)


def test_extension_renders_without_system_embree_or_tbb(extension_zip, tmp_path):
    if shutil.which("unshare") is None or subprocess.run(
            ["unshare", "--mount", "true"], capture_output=True).returncode != 0:
        pytest.skip("no private mount namespace here (unshare --mount needs root or CAP_SYS_ADMIN)")
    result = install_and_render(extension_zip, tmp_path, hiding(system_libraries()))
    # Only the wheel's Embree and TBB, and those bpy bundles, were mapped; nothing of the system's.
    bpy_dir = Path(importlib.util.find_spec("bpy").submodule_search_locations[0]).resolve()
    wheels_site = Path(result["files"]["photic"]).parents[1]
    for path in result["mapped"]:
        assert Path(path).is_relative_to(wheels_site) or Path(path).is_relative_to(bpy_dir), path
