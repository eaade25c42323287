#!/usr/bin/env python3
"""Install the Photic add-on into a distribution Blender (e.g. Debian's 3.4) as a legacy add-on.

Run it with the Python whose site-packages hold the engine (the repository's virtual
environment), so that the installed copy can find ``photic``:

    .venv/bin/python scripts/install_blender_addon.py            # copy into Blender's user scripts
    .venv/bin/python scripts/install_blender_addon.py --link     # symlink instead (development)
    .venv/bin/python scripts/install_blender_addon.py --enable   # also enable it in the user prefs
    .venv/bin/python scripts/install_blender_addon.py --scripts /tmp/bscripts   # another scripts dir

What it does:

1. finds the scripts directory: ``--scripts DIR``, else ``$BLENDER_USER_SCRIPTS``, else the user
   scripts directory that the Blender binary reports (``bpy.utils.script_path_user()``);
2. copies (or with ``--link`` symlinks) ``blender_addon/`` to ``<scripts>/addons/photic_blender``;
3. writes ``site_packages.txt`` into it: this Python's site-packages, one per line, which
   ``engine_loader.py`` adds with ``site.addsitedir`` (with ``--link`` the file is written into
   the source tree's ``blender_addon/``, where git ignores it);
4. with ``--enable``: runs Blender once to enable the add-on and save the user preferences.

Then, for example:

    blender -b example_blends/canonical_problem2.blend -E PHOTIC -o /tmp/out/frame_#### -f 1

Without saved preferences (nothing written to Blender's user config), enable it per run:

    BLENDER_USER_SCRIPTS=<scripts> blender -b --addons photic_blender FILE.blend -E PHOTIC \\
        -o /tmp/out/frame_#### -F OPEN_EXR_MULTILAYER -f 1

Blender handles its arguments in order: ``--addons`` before anything needing the add-on
(``-E PHOTIC``, a ``--python-expr`` using ``scene.photic``, ``-f``; before the .blend file it
also avoids the "Engine 'PHOTIC' not available" note when the file is read), and ``-o``/``-F``
before ``-f``. That writes ``/tmp/out/frame_0001.exr`` (multilayer: Combined and the Photic
passes) and ``frame_0001_radiometers.csv``/``.json`` beside it.
"""
from __future__ import annotations

import argparse
import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

MODULE = "photic_blender"
ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "blender_addon"
LISTING = "site_packages.txt"
MARKER = "PHOTIC_SCRIPTS_DIR="


def blender_scripts_dir(blender: str) -> Path:
    """The user scripts directory of this Blender (honours BLENDER_USER_SCRIPTS/_CONFIG)."""
    expr = f"import bpy; print('{MARKER}' + bpy.utils.script_path_user())"
    out = subprocess.run([blender, "-b", "--factory-startup", "--python-expr", expr],
                         capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        if line.startswith(MARKER):
            return Path(line[len(MARKER):].strip())
    raise SystemExit(f"could not read the user scripts directory from {blender}:\n{out}")


def engine_site_packages() -> list[str]:
    """The site-packages directories of this Python that can import ``photic``."""
    dirs = [d for d in site.getsitepackages() if Path(d).is_dir()]
    return dirs


def check_engine() -> None:
    try:
        import photic._core  # noqa: F401
    except ImportError as exc:
        print(f"warning: this Python ({sys.executable}) cannot import photic._core ({exc}); "
              f"the add-on will say the engine is missing. Run this script with the venv's "
              f"Python (.venv/bin/python).", file=sys.stderr)


def install(dest: Path, link: bool) -> Path:
    """Copy or link blender_addon/ to dest; returns the directory where site_packages.txt goes."""
    if dest.is_symlink() or dest.is_file():
        dest.unlink()
    elif dest.is_dir():
        shutil.rmtree(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    if link:
        dest.symlink_to(SOURCE, target_is_directory=True)
        print(f"linked {dest} -> {SOURCE}")
        return SOURCE
    shutil.copytree(SOURCE, dest, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "pyproject.toml", LISTING))
    print(f"copied {SOURCE} to {dest}")
    return dest


def enable(blender: str, env: dict, scripts: Path | None) -> None:
    """Enable the add-on and save the user preferences. For a ``--scripts`` directory, also
    record it as the preferences' scripts path (when none is set) so later runs find it."""
    expr = ("import bpy, sys\n"
            f"scripts = {str(scripts) if scripts else ''!r}\n"
            "paths = bpy.context.preferences.filepaths\n"
            "if scripts and not paths.script_directory:\n"
            "    paths.script_directory = scripts\n"
            "elif scripts and paths.script_directory != scripts:\n"
            "    print('PHOTIC_NOTE=the preferences already name the scripts directory ' + "
            "paths.script_directory + '; set BLENDER_USER_SCRIPTS=' + scripts + ' for each run')\n"
            f"bpy.ops.preferences.addon_enable(module='{MODULE}')\n"
            f"import addon_utils\n"
            f"loaded, _ = addon_utils.check('{MODULE}')\n"
            "bpy.ops.wm.save_userpref()\n"
            "import os\n"
            "print('PHOTIC_PREFS=' + os.path.join(bpy.utils.user_resource('CONFIG'), "
            "'userpref.blend'))\n"
            "print('PHOTIC_ENABLED=' + str(loaded))\n"
            "sys.exit(0 if loaded else 1)\n")
    proc = subprocess.run([blender, "-b", "--python-expr", expr], capture_output=True, text=True,
                          env=env)
    if proc.returncode != 0 or "PHOTIC_ENABLED=True" not in proc.stdout:
        sys.stderr.write(proc.stdout + proc.stderr)
        raise SystemExit(f"enabling {MODULE} in {blender} failed")
    prefs = "Blender's user configuration folder"
    for line in proc.stdout.splitlines():
        if line.startswith("PHOTIC_NOTE="):
            print("note: " + line[len("PHOTIC_NOTE="):])
        if line.startswith("PHOTIC_PREFS="):
            prefs = line[len("PHOTIC_PREFS="):]
    # (which file: with BLENDER_USER_CONFIG naming a folder that does not exist, Blender
    # falls back to the user's own ~/.config/blender, issue 49)
    print(f"enabled {MODULE} and saved the user preferences of {blender} in {prefs}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scripts", type=Path,
                    help="Blender scripts directory to install into (default: $BLENDER_USER_SCRIPTS "
                         "or the user scripts directory reported by Blender)")
    ap.add_argument("--blender", default=os.environ.get("BLENDER", "blender"),
                    help="Blender binary (default: $BLENDER or 'blender' on PATH)")
    ap.add_argument("--link", action="store_true", help="symlink blender_addon/ instead of copying it")
    ap.add_argument("--enable", action="store_true",
                    help="run Blender once to enable the add-on and save the user preferences")
    args = ap.parse_args(argv)

    blender = shutil.which(args.blender) or args.blender
    env = dict(os.environ)
    if args.scripts is not None:
        scripts = args.scripts.resolve()
        env["BLENDER_USER_SCRIPTS"] = str(scripts)
    elif os.environ.get("BLENDER_USER_SCRIPTS"):
        scripts = Path(os.environ["BLENDER_USER_SCRIPTS"]).resolve()
    else:
        if not shutil.which(blender):
            raise SystemExit(f"Blender binary '{args.blender}' not found: pass --blender or --scripts")
        scripts = blender_scripts_dir(blender)
    print(f"scripts directory: {scripts}")

    check_engine()
    dest = scripts / "addons" / MODULE
    listing_dir = install(dest, args.link)
    dirs = engine_site_packages()
    (listing_dir / LISTING).write_text("".join(d + "\n" for d in dirs))
    print(f"wrote {listing_dir / LISTING}: " + ", ".join(dirs))

    if args.enable:
        if not shutil.which(blender):
            raise SystemExit(f"Blender binary '{args.blender}' not found: cannot --enable")
        enable(blender, env, args.scripts.resolve() if args.scripts else None)
    else:
        print(f"not enabled: pass --enable, or add '--addons {MODULE}' to each blender command line")
    prefix = "" if args.scripts is None else f"BLENDER_USER_SCRIPTS={scripts} "
    addons = "" if args.enable else f"--addons {MODULE} "
    print(f"render with: {prefix}blender -b {addons}FILE.blend -E PHOTIC -o //render/frame_#### -f 1")
    return 0


if __name__ == "__main__":
    sys.exit(main())
