"""Integrity and security (issue 49, kind 7): the add-on decides 'this machine' by parsing the
scheduler's host, not by its first characters; a batch unit is trusted on resume only with
this user's keyed digest over the job's parameters and the unit (a forged unit with a
recomputed checksum was reused: Ed 1.76 -> 1761); Dask renders from Blender keep units in a
private per-user folder, not a shared /tmp/photic_dask; a name that a spreadsheet would take
for a formula is written as text in the CSV tables."""
from __future__ import annotations

import csv
import json
import os
import stat

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from photic.distributed import load_job, run_job
from photic.distributed.store import UnitStore, arrays_digest, cache_dir, private_dir, unit_key
from photic.output import csv_text, write_outputs
from photic.render import render
from photic.scene import Scene

from test_robustness import small


# ---- the scheduler's host ------------------------------------------------------------------

@pytest.mark.parametrize("host, local", [
    ("127.0.0.1", True), ("127.1.2.3", True), ("::1", True), ("[::1]", True), ("localhost", True),
    ("127.attacker.example", False), ("127.0.0.1.nip.io", False), ("localhost.attacker.example", False),
    ("10.0.0.5", False), ("0.0.0.0", False), ("::ffff:10.0.0.1", False), ("127", False), ("", False),
])
def test_only_loopback_addresses_and_localhost_are_this_machine(host, local):
    pytest.importorskip("bpy")
    from photic_blender.final_render import is_this_machine, remote_scheduler_refusal
    assert is_this_machine(host) is local
    if host:
        refusal = remote_scheduler_refusal(f"tcp://{host}:8786", False)
        assert (refusal is None) is local, refusal


@settings(max_examples=100, deadline=None)
@given(st.from_regex(r"127\.[a-z0-9.-]{1,20}", fullmatch=True))
def test_no_name_beginning_with_127_skips_the_consent(host):
    pytest.importorskip("bpy")
    import ipaddress
    from photic_blender.final_render import remote_scheduler_refusal
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    assert (remote_scheduler_refusal(f"tcp://{host}:8786", False) is None) == loopback


# ---- units bound to their job ----------------------------------------------------------------

def _forge(path, factor: float) -> None:
    """Scale a stored unit's sums and recompute its checksum, as the issue's forger did."""
    with np.load(path, allow_pickle=False) as f:
        meta = json.loads(str(f["__meta__"]))
        arrays = {k: f[k] for k in f.files if k != "__meta__"}
    arrays = {k: (v * factor if k == "s" else v * factor * factor if k == "s2" else v)
              for k, v in arrays.items()}
    meta["sha256"] = arrays_digest(arrays)
    np.savez(path, __meta__=np.array(json.dumps(meta)), **arrays)


@pytest.fixture
def tiny_job(tmp_path):
    d = small()
    d["cameras"] = []
    d["radiometer_arrays"] = []
    (tmp_path / "scene.json").write_text(json.dumps(d))
    (tmp_path / "job.json").write_text(json.dumps({"photic_job": 1, "name": "j", "inputs": ["scene.json"],
                                                   "radiometer_samples": 2048}))
    return load_job(tmp_path / "job.json")


def _ed(report_dir) -> float:
    doc = json.loads((report_dir / "results" / "scene" / "test_radiometers.json").read_text())
    return next(r for r in doc["radiometers"] if r["name"] == "Ed_1m")["value"][0][0]


def test_a_forged_unit_with_a_recomputed_checksum_is_computed_again(tmp_path, tiny_job):
    out = tmp_path / "out"
    first = run_job(tiny_job, out, workers=0, progress=False)
    ed = _ed(out)
    units = sorted((out / "units").rglob("*.npz"))
    assert units and first.ok
    for u in units:
        _forge(u, 1000.0)
    again = run_job(tiny_job, out, workers=0, progress=False)
    assert len(again.computed) == len(units) and not again.skipped  # none trusted
    assert _ed(out) == ed


def test_units_written_under_another_key_are_not_trusted(tmp_path, tiny_job, monkeypatch):
    out = tmp_path / "out"
    run_job(tiny_job, out, workers=0, progress=False)
    monkeypatch.setenv("PHOTIC_CONFIG_DIR", str(tmp_path / "someone-else"))
    again = run_job(tiny_job, out, workers=0, progress=False)
    assert again.computed and not again.skipped
    monkeypatch.undo()
    third = run_job(tiny_job, out, workers=0, progress=False)  # theirs now: computed again
    assert third.computed and not third.skipped
    fourth = run_job(tiny_job, out, workers=0, progress=False)  # ours: reused
    assert not fourth.computed and fourth.skipped


def test_the_unit_key_is_private_and_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("PHOTIC_CONFIG_DIR", str(tmp_path / "cfg"))
    k1, k2 = unit_key(), unit_key()
    assert k1 == k2 and len(k1) == 32
    assert stat.S_IMODE(os.stat(tmp_path / "cfg").st_mode) == 0o700
    assert stat.S_IMODE(os.stat(tmp_path / "cfg" / "unit-key").st_mode) == 0o600
    assert UnitStore(tmp_path).key == k1


# ---- the Dask cache -----------------------------------------------------------------------------

def test_the_dask_cache_is_a_private_folder_of_this_user(tmp_path, monkeypatch):
    monkeypatch.delenv("PHOTIC_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    folder = private_dir(cache_dir() / "dask")
    assert folder == tmp_path / "xdg" / "photic" / "dask"
    assert stat.S_IMODE(os.stat(folder).st_mode) == 0o700
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    os.chmod(shared, 0o777)
    private_dir(shared)
    assert stat.S_IMODE(os.stat(shared).st_mode) == 0o700  # made private
    link = tmp_path / "link"
    link.symlink_to(folder)
    with pytest.raises(OSError, match="link"):
        private_dir(link)


def test_the_addon_no_longer_uses_a_shared_tmp_folder():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "blender_addon" / "final_render.py").read_text()
    assert 'gettempdir()) / "photic_dask"' not in text and "private_dir(cache_dir()" in text


# ---- spreadsheet formulas ---------------------------------------------------------------------

@given(st.text(max_size=20))
def test_csv_text_never_starts_a_formula(text):
    cell = csv_text(text)
    assert not cell.startswith(("=", "+", "-", "@", "\t", "\r"))
    assert cell in (text, "'" + text)


def test_a_radiometer_named_like_a_formula_is_text_in_the_csv(tmp_path):
    d = small()
    d["radiometers"][0]["name"] = '=HYPERLINK("http://x.example","1")'
    d["radiometers"].append({"name": "+1+2", "quantity": "Ed", "position": [0, 0, -2]})
    res = render(Scene.from_dict(d), samples=1, radiometer_samples=256)
    written = write_outputs(tmp_path, res)
    for path in written["tables"]:
        if path.suffix == ".csv":
            rows = list(csv.reader(line for line in path.read_text().splitlines()
                                   if not line.startswith("#")))
            for row in rows:
                for cell in row:
                    assert not cell.startswith(("=", "+", "@")), (path.name, cell)
    doc = json.loads(written["tables"][1].read_text())
    assert doc["radiometers"][0]["name"] == d["radiometers"][0]["name"]  # the JSON as it is
