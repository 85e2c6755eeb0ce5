"""A result directory written before the runner was split (tests/data/run_before_runner_split, made by
the 0.2.0 runner) resumes with the split one: same manifest fingerprint, same chunk layout, same bytes."""

import dataclasses
import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
from hypothesis import given
from hypothesis import strategies as st

from socialnav.evaluate.chunks import CHUNK_STAMP_KEY
from socialnav.evaluate.manifest import manifest_stamp, run_identity
from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset

OLD_RUN = Path(__file__).resolve().parents[1] / "data" / "run_before_runner_split"


def old_run_settings():
    """The arguments the stored run was made with (chunks of 2 episodes, 3 per scenario)."""
    preset = load_preset("wang2022")
    preset = dataclasses.replace(
        preset, evaluation=dataclasses.replace(preset.evaluation, episodes=3, chunk_size=2)
    )
    return preset, {"scenarios": ["circle_crossing", "passing"], "episodes": 3, "visibility": "invisible"}


def copy_of_old_run(tmp_path: Path) -> Path:
    out = tmp_path / "run"
    shutil.copytree(OLD_RUN, out)
    return out


def files_by_name(out: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(out)): p.read_bytes()
        for sub in ("episodes", "trajectories")
        for p in sorted((out / sub).rglob("*.parquet"))
    }


def test_the_stored_run_has_the_layout_the_runner_expects():
    names = set(files_by_name(OLD_RUN))
    for kind in ("episodes", "trajectories"):
        for cell in ("circle_crossing__invisible", "passing__invisible"):
            assert {f"{kind}/{cell}/00000-00002.parquet", f"{kind}/{cell}/00002-00003.parquet"} <= names
    assert len(names) == 8


def test_its_manifest_fingerprint_is_the_one_stamped_in_its_chunks():
    stamp = manifest_stamp(json.loads((OLD_RUN / "manifest.json").read_text()))
    for path in (OLD_RUN / "episodes").rglob("*.parquet"):
        assert pq.read_schema(path).metadata[CHUNK_STAMP_KEY.encode()].decode() == stamp


def test_an_old_run_resumes_without_recomputing_anything(tmp_path):
    out = copy_of_old_run(tmp_path)
    before = files_by_name(out)
    manifest_before = (out / "manifest.json").read_bytes()
    preset, args = old_run_settings()
    result = run_protocol(make_policy("orca"), preset, out, progress=False, workers=0, **args)
    assert result.computed_episodes == 0
    assert [(r["scenario"], r["index"]) for r in result.rows] == [
        (s, i) for s in ("circle_crossing", "passing") for i in range(3)
    ]
    assert files_by_name(out) == before  # nothing rewritten
    assert (out / "manifest.json").read_bytes() == manifest_before  # the first run's record stands
    # the conclusion from the old chunks is the one the old runner wrote, with the field added since:
    # single_human, which table a row belongs to
    old_summary = json.loads((OLD_RUN / "summary.json").read_text())
    new_summary = json.loads((out / "summary.json").read_text())
    assert [r.pop("single_human") for r in new_summary["rows"]] == [
        r["scenario"] == "passing" for r in old_summary["rows"]]
    assert new_summary == old_summary


def test_a_missing_chunk_of_an_old_run_is_recomputed_to_the_same_bytes(tmp_path):
    out = copy_of_old_run(tmp_path)
    before = files_by_name(out)
    for kind in ("episodes", "trajectories"):
        (out / kind / "passing__invisible" / "00002-00003.parquet").unlink()
    preset, args = old_run_settings()
    result = run_protocol(make_policy("orca"), preset, out, progress=False, workers=0, **args)
    assert result.computed_episodes == 1  # only episode 2 of passing
    assert files_by_name(out) == before


manifest_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=8,
)


@given(st.dictionaries(st.text(min_size=1, max_size=6), manifest_values, max_size=5), st.text(max_size=6))
def test_the_fingerprint_ignores_key_order_and_the_release(manifest, version):
    stamp = manifest_stamp(manifest)
    assert len(stamp) == 32 and int(stamp, 16) >= 0
    shuffled = dict(reversed(list(manifest.items())))
    assert manifest_stamp(shuffled) == stamp
    assert manifest_stamp({**manifest, "socialnav_version": version}) == manifest_stamp(
        {k: v for k, v in manifest.items() if k != "socialnav_version"}
    )
    assert run_identity({**manifest, "socialnav_version": version}).get("socialnav_version") is None


def test_the_fingerprint_of_a_known_manifest_is_unchanged():
    # Hand-checked value: sha256 of '{"a":1,"cells":[]}' truncated to 32 hex digits. A change here
    # would orphan every existing result directory.
    assert manifest_stamp({"cells": [], "a": 1, "socialnav_version": "9"}) == (
        "fbc34af18309ae89fd897d854dcea091"
    )
