"""Inputs of the bad-input corpus (test_bad_input_corpus.py): the cases and the files they read."""

from __future__ import annotations

import csv
import fractions
import os
import shutil
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Case:
    id: str
    kind: str  # file, setting, bounds, out, checkpoint, mismatch, resume, type
    argv: tuple[str, ...]  # "{base}" is the corpus directory
    expect: tuple[str, ...]  # substrings of the one error line
    code: int = 2
    fsize: int | None = None  # RLIMIT_FSIZE of the case's process: a "full disk"
    untouched: tuple[str, ...] = ()  # paths (relative to base) that must not exist afterwards


def C(id, kind, argv, *expect, **kw):  # noqa: N802 (a table reads better with a short name)
    return Case(id, kind, tuple(argv.split()), tuple(expect), **kw)


EV = "evaluate --no-progress --episodes 2 --scenario circle_crossing --preset crowdnav"
EV_SARL = "evaluate --no-progress --episodes 2 --policy sarl"
TR = "train --policy sarl --no-progress --rl-episodes 1"

CASES: list[Case] = [
    # -- metrics: the input file -----------------------------------------------------------------
    C("metrics-missing", "file", "metrics {base}/nope.parquet", "{base}/nope.parquet", "no such file"),
    C("metrics-dir", "file", "metrics {base}/adir.parquet", "adir.parquet", "is a directory"),
    C("metrics-suffix", "file", "metrics {base}/log.txt", "log.txt"),
    C("metrics-empty-csv", "file", "metrics {base}/empty.csv", "empty.csv"),
    C("metrics-header-only", "file", "metrics {base}/header_only.csv", "header_only.csv", "no episodes"),
    C("metrics-not-numeric", "type", "metrics {base}/text_x.csv", "text_x.csv", "column 'x'", "not numeric"),
    # A log without goals is scored with assumed goals (a note says so: docs/real_world_logs.md); one
    # without y cannot be scored at all.
    C("metrics-missing-column", "file", "metrics {base}/no_y.csv", "no_y.csv", "'y'"),
    C("metrics-nan", "type", "metrics {base}/nan_x.csv", "nan_x.csv", "column 'x', row 1"),
    C(
        "metrics-huge-id",
        "bounds",
        "metrics {base}/huge_id.csv",
        "huge_id.csv",
        "column 'agent', row 1",
        "int64",
    ),
    C("metrics-float-id", "type", "metrics {base}/float_id.csv", "float_id.csv", "column 'agent'", "integer"),
    C("metrics-no-robot", "file", "metrics {base}/no_robot.csv", "no_robot.csv", "no robot"),
    C("metrics-binary-csv", "file", "metrics {base}/binary.csv", "binary.csv"),
    C("metrics-corrupt-parquet", "file", "metrics {base}/corrupt.parquet", "corrupt.parquet", "damaged"),
    C("metrics-truncated-parquet", "file", "metrics {base}/truncated.parquet", "truncated.parquet"),
    C("metrics-text-parquet", "file", "metrics {base}/text.parquet", "text.parquet"),
    C(
        "metrics-resample-tiny-dt",
        "bounds",
        "metrics {base}/log.csv --resample --dt 1e-9",
        "more than the 1000000 allowed",
        "--dt",
    ),
    C("metrics-dt-negative", "bounds", "metrics {base}/log.csv --resample --dt -1", "--dt", "-1"),
    C("metrics-dt-nan", "bounds", "metrics {base}/log.csv --resample --dt nan", "--dt", "nan"),
    C("metrics-dt-inf", "bounds", "metrics {base}/log.csv --resample --dt inf", "--dt", "inf"),
    C("metrics-irregular", "file", "metrics {base}/irregular.csv", "irregular.csv", "resample"),
    # -- evaluate: presets ---------------------------------------------------------------------
    C("preset-unknown", "setting", "evaluate --preset nowhere", "unknown preset 'nowhere'"),
    C("preset-missing-file", "file", "evaluate --preset {base}/nope.yaml", "nope.yaml", "does not exist"),
    C("preset-dir", "file", "evaluate --preset {base}/adir.parquet", "adir.parquet", "is a directory"),
    C("preset-binary", "file", "evaluate --preset {base}/binary.yaml", "binary.yaml"),
    C("preset-bad-yaml", "file", "evaluate --preset {base}/bad_yaml.yaml", "bad_yaml.yaml", "not valid YAML"),
    C("preset-list", "type", "evaluate --preset {base}/list.yaml", "list.yaml", "must be a mapping"),
    C("preset-scalar", "type", "evaluate --preset {base}/scalar.yaml", "scalar.yaml", "must be a mapping"),
    C(
        "preset-world-5",
        "type",
        "evaluate --preset {base}/world5.yaml",
        "world5.yaml",
        "section world",
        "must be a mapping",
        "5",
    ),
    C("preset-orca-list", "type", "evaluate --preset {base}/orca_list.yaml", "world.orca", "mapping"),
    C(
        "preset-policies-list",
        "type",
        "evaluate --preset {base}/policies_list.yaml",
        "policies",
        "must be a mapping",
    ),
    C(
        "preset-policy-params-5",
        "type",
        "evaluate --preset {base}/policy_5.yaml",
        "policies.orca",
        "mapping",
        "5",
    ),
    C(
        "preset-scenarios-string",
        "type",
        "evaluate --preset {base}/scen_str.yaml",
        "evaluation.multi_human must be a list",
    ),
    C(
        "preset-duplicate-scenario",
        "setting",
        "evaluate --preset {base}/dup.yaml",
        "evaluation.multi_human",
        "random twice",
    ),
    C("preset-unknown-key", "setting", "evaluate --preset {base}/unknown_key.yaml", "world.horizon"),
    C("preset-dt-string", "type", "evaluate --preset {base}/dt_str.yaml", "dt", "must be a number", "fast"),
    C(
        "preset-threads-huge",
        "bounds",
        "evaluate --preset {base}/threads.yaml",
        "threads",
        "[0, 256]",
        "100000",
    ),
    C("preset-threads-negative", "bounds", "evaluate --preset {base}/threads_neg.yaml", "threads", "-1"),
    C("preset-dt-tiny", "bounds", "evaluate --preset {base}/dt_tiny.yaml", "dt", "1e-09", ">= 0.0001"),
    C("preset-dt-zero", "bounds", "evaluate --preset {base}/dt_zero.yaml", "dt", "> 0"),
    C(
        "preset-time-limit-huge",
        "bounds",
        "evaluate --preset {base}/time_limit.yaml",
        "time_limit",
        "1000000000.0",
        "more than the 100000 allowed",
    ),
    C(
        "preset-continuation-huge",
        "bounds",
        "evaluate --preset {base}/cap.yaml --visibility visible",
        "continuation_cap",
        "more than the 100000 allowed",
    ),
    C("preset-v-pref-nan", "bounds", "evaluate --preset {base}/vpref_nan.yaml", "robot.v_pref", "finite"),
    C("preset-v-pref-inf", "bounds", "evaluate --preset {base}/vpref_inf.yaml", "robot.v_pref", "finite"),
    C(
        "preset-humans-huge",
        "bounds",
        "evaluate --preset {base}/humans.yaml",
        "evaluation.n_humans",
        "must be in [1, 1000], got 100000",
    ),
    C(
        "preset-episodes-huge-int",
        "bounds",
        "evaluate --preset {base}/episodes_huge.yaml",
        "evaluation.episodes",
        "must be in [1, 10000000]",
    ),
    # -- evaluate: options ---------------------------------------------------------------------
    C("ev-episodes-0", "setting", EV + " --episodes 0", "episodes must be >= 1"),
    C("ev-episodes-huge", "bounds", EV + " --episodes 1000000000000", "episodes must be <= 10000000"),
    C("ev-episodes-split", "bounds", EV + " --episodes 1001 --out {base}/o_split",
      "circle_crossing: 1001 episodes", "more than the 1000 of the 'test' split", untouched=("o_split",)),
    C("ev-batch-0", "setting", EV + " --batch-size 0", "--batch-size must be >= 1"),
    C(
        "ev-batch-huge",
        "bounds",
        "evaluate --no-progress --scenario circle_crossing --preset {base}/train_split.yaml --batch-size "
        "100000000 --episodes 1000000 --out {base}/o_batch",
        "GiB",
        "allowed",
        untouched=("o_batch",),
    ),
    C("ev-scenario-twice", "setting", EV + " --scenario random random", "random given more than once"),
    C("ev-scenario-unknown", "setting", EV + " --scenario plaza", "unknown scenario 'plaza'"),
    C("ev-policy-unknown", "setting", EV + " --policy teleport", "unknown policy 'teleport'"),
    C("ev-checkpoint-not-learned", "setting", EV + " --checkpoint {base}/sarl.pt", "is not learned"),
    # om_sarl ships for wang2022 only
    C("ev-learned-no-checkpoint", "setting", "evaluate --policy om_sarl --preset crowdnav",
      "pass --checkpoint"),
    # -- evaluate: the output directory -----------------------------------------------------------
    C("ev-out-is-file", "out", EV + " --out {base}/afile", "afile", "not a directory"),
    C("ev-out-parent-is-file", "out", EV + " --out {base}/afile/sub", "afile", "not a directory"),
    C("ev-out-unwritable", "out", EV + " --out /sys/socialnav-corpus/out", "/sys/socialnav-corpus"),
    C(
        "ev-out-disk-full",
        "out",
        EV + " --out {base}/o_full",
        "cannot write {base}/o_full/",
        "File too large",
        fsize=600,
        untouched=("o_full/manifest.json",),
    ),
    C("ev-out-locked", "resume", EV + " --out {base}/locked", "in use by another evaluation", "pid"),
    C(
        "ev-out-other-run",
        "resume",
        EV.replace("--episodes 2", "--episodes 3") + " --out {base}/run_a",
        "cells[circle_crossing/invisible].episodes: 2 -> 3",
    ),
    C(
        "ev-out-other-policy",
        "resume",
        EV + " --out {base}/run_a2 --label other",
        'policy.label: "orca" -> "other"',
    ),
    C("ev-out-damaged-manifest", "resume", EV + " --out {base}/run_bad_manifest", "manifest.json", "damaged"),
    C("ev-out-foreign-chunk", "resume", EV + " --out {base}/run_foreign_name", "is not part of this run"),
    C(
        "ev-out-chunk-of-other-run",
        "resume",
        EV + " --out {base}/run_foreign_stamp",
        "00000-00002.parquet does not belong to this run",
    ),
    C("ev-out-corrupt-chunk", "resume", EV + " --out {base}/run_corrupt", "00000-00002.parquet", "damaged"),
    # -- evaluate: checkpoints ---------------------------------------------------------------------
    C("ckpt-missing", "checkpoint", EV_SARL + " --checkpoint {base}/nope.pt", "nope.pt", "does not exist"),
    C("ckpt-dir", "checkpoint", EV_SARL + " --checkpoint {base}/adir.parquet", "is a directory"),
    C("ckpt-empty", "checkpoint", EV_SARL + " --checkpoint {base}/empty.pt", "empty.pt", "is empty"),
    C("ckpt-garbage", "checkpoint", EV_SARL + " --checkpoint {base}/garbage.pt", "garbage.pt", "damaged"),
    C("ckpt-truncated", "checkpoint", EV_SARL + " --checkpoint {base}/truncated.pt", "truncated.pt"),
    C("ckpt-pickle", "checkpoint", EV_SARL + " --checkpoint {base}/pickle.pt", "pickle.pt", "refused",
      "fractions.Fraction"),
    C(
        "ckpt-not-dict",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/list.pt",
        "list.pt",
        "not a socialnav learned-policy checkpoint: it holds a list, expected format",
    ),
    C(
        "ckpt-no-state-dict",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/no_state.pt",
        "no_state.pt",
        "'state_dict'",
        "missing",
    ),
    C(
        "ckpt-input-dim-str",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/dim_str.pt",
        "'input_dim'",
        "must be a int",
    ),
    C(
        "ckpt-bad-kwargs",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/kwargs.pt",
        "kwargs.pt",
        "cannot be rebuilt",
    ),
    C(
        "ckpt-bad-shapes",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/shapes.pt",
        "shapes.pt",
        "cannot be rebuilt",
    ),
    C(
        "ckpt-value-policy-5",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/vp5.pt",
        "config.value_policy must be a mapping",
    ),
    C(
        "ckpt-value-policy-key",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/vpkey.pt",
        "unknown key(s) bogus",
    ),
    C(
        "ckpt-value-policy-value",
        "checkpoint",
        EV_SARL + " --checkpoint {base}/vpval.pt",
        "vpval.pt",
        "invalid",
    ),
    C(
        "ckpt-other-policy",
        "checkpoint",
        "evaluate --no-progress --policy cadrl --checkpoint {base}/sarl.pt",
        "holds policy 'sarl'",
        "expected 'cadrl'",
    ),
    C(
        "mismatch-v-pref",
        "mismatch",
        EV_SARL + " --preset crowdnav --checkpoint {base}/sarl.pt",
        "robot.v_pref 1.5 in the checkpoint, 1.0 in preset 'crowdnav'",
        "--allow-preset-mismatch",
    ),
    C(
        "mismatch-dt-by-name",
        "mismatch",
        EV_SARL + " --preset {base}/crowdnav_dt.yaml",
        "dt 0.25 in the checkpoint, 0.1 in preset 'crowdnav'",
    ),
    C(
        "mismatch-kinematics",
        "mismatch",
        EV_SARL + " --preset {base}/unicycle.yaml --checkpoint {base}/sarl.pt",
        "kinematics 'holonomic' in the checkpoint, 'unicycle'",
    ),
    C(
        "mismatch-reward",
        "mismatch",
        EV_SARL + " --preset {base}/reward.yaml --checkpoint {base}/sarl.pt",
        "reward.success_reward 1.0 in the checkpoint, 2.0",
    ),
    # -- train -----------------------------------------------------------------------------------
    C(
        "train-not-learned",
        "setting",
        "train --policy orca --out {base}/t_orca",
        "--policy 'orca': not a policy that `socialnav train` trains",
        untouched=("t_orca",),
    ),
    C("train-config-missing", "file", TR + " --config {base}/nope.yaml", "nope.yaml", "does not exist"),
    C("train-config-dir", "file", TR + " --config {base}/adir.parquet", "is a directory"),
    C("train-config-list", "type", TR + " --config {base}/list.yaml", "list.yaml", "mapping"),
    C("train-config-binary", "file", TR + " --config {base}/binary.yaml", "binary.yaml"),
    C("train-rl-5", "type", TR + " --config {base}/rl5.yaml", "section rl must be a mapping"),
    C("train-rl-list", "type", TR + " --config {base}/rl_list.yaml", "section rl must be a mapping"),
    C("train-imitation-negative", "bounds", TR + " --config {base}/il_neg.yaml", "imitation.epochs", ">= 0"),
    C("train-unknown-key", "setting", TR + " --config {base}/train_key.yaml", "rl.episodez"),
    C("train-lr-string", "type", TR + " --config {base}/lr_str.yaml", "rl.lr", "must be a number"),
    C("train-collection-0", "setting", TR + " --collection-batch 0", "--collection-batch", ">= 1"),
    C(
        "train-rl-episodes-negative",
        "setting",
        TR.replace("--rl-episodes 1", "--rl-episodes -1"),
        "--rl-episodes",
        ">= 0",
    ),
    C("train-seed-negative", "setting", TR + " --seed -1", "--seed: seed", "must be in [0, 4294967295]"),
    C("train-preset-world-5", "type", TR + " --preset {base}/world5.yaml", "section world"),
    C(
        "train-preset-threads",
        "bounds",
        TR + " --preset {base}/threads.yaml --out {base}/t_threads",
        "threads",
        untouched=("t_threads",),
    ),
    C(
        "train-preset-dt-tiny",
        "bounds",
        TR + " --preset {base}/dt_tiny.yaml --out {base}/t_dt",
        "dt",
        untouched=("t_dt",),
    ),
    C("train-out-is-file", "out", TR + " --out {base}/afile", "afile", "not a directory"),
    C("train-out-locked", "resume", TR + " --out {base}/t_locked", "in use by another training"),
    C("train-last-garbage", "checkpoint", TR + " --out {base}/t_garbage", "last.pt", "damaged"),
    C("train-last-not-state", "resume", TR + " --out {base}/t_notstate", "not a training state"),
]


if not os.path.exists("/dev/nvidia0"):  # where CUDA exists, --device cuda is no mistake
    CASES.append(
        C("train-cuda", "setting", TR + " --device cuda --out {base}/t_cuda", "cuda", untouched=("t_cuda",))
    )


def _yaml(base: Path, name: str, text: str) -> None:
    (base / name).write_text(text)


def build_inputs(base: Path):
    """Writes every input file of the corpus under ``base``; returns a lock to release afterwards."""
    import numpy as np
    import torch

    from socialnav._io import DirectoryLock
    from socialnav.evaluate.runner import run_protocol
    from socialnav.policies import make_policy
    from socialnav.presets import load_preset
    from socialnav.scenarios import make_scenario
    from socialnav.sim.settings import WorldSettings
    from socialnav.sim.world import World
    from socialnav.trajectory import write_trajectories

    # trajectory files
    with World(WorldSettings(), make_scenario("passing", n_humans=1, robot_v_pref=1.0), 2, count=2) as world:
        policy = make_policy("orca", safety_space=0.2)
        world.reset()
        trajs = []
        while world.busy:
            trajs += world.step(policy.act(world.observe())).finished
    write_trajectories(base / "log.csv", trajs)
    write_trajectories(base / "log.parquet", trajs)
    with open(base / "log.csv", newline="") as f:
        table = list(csv.reader(f))
    cols, rows = table[0], table[1:]

    def write_csv(name: str, header: list[str], body: list[list[str]]) -> None:
        with open(base / name, "w", newline="") as f:
            csv.writer(f).writerows([header, *body])

    def with_value(name: str, column: str, value: str) -> None:
        body = [list(r) for r in rows]
        body[0][cols.index(column)] = value
        write_csv(name, cols, body)

    (base / "adir.parquet").mkdir()
    (base / "log.txt").write_text("hello\n")
    (base / "empty.csv").write_text("")
    write_csv("header_only.csv", cols, [])
    with_value("text_x.csv", "x", "abc")
    with_value("nan_x.csv", "x", "")
    with_value("huge_id.csv", "agent", str(10**30))
    with_value("float_id.csv", "agent", "0.5")
    keep = [i for i, c in enumerate(cols) if c != "y"]
    write_csv("no_y.csv", [cols[i] for i in keep], [[r[i] for i in keep] for r in rows])
    write_csv("no_robot.csv", cols, [r for r in rows if r[cols.index("agent")] != "0"])
    (base / "binary.csv").write_bytes(bytes(range(256)) * 8)
    t = cols.index("t")
    write_csv(
        "irregular.csv",
        cols,
        [
            [f"{float(c) * 1.013:.6f}" if i == t and k % 3 == 1 else c for i, c in enumerate(r)]
            for k, r in enumerate(rows)
        ],
    )
    data = bytearray((base / "log.parquet").read_bytes())
    (base / "truncated.parquet").write_bytes(bytes(data[: len(data) // 2]))
    for i in range(len(data) // 3, len(data) // 3 + 16):
        data[i] ^= 0x5A
    (base / "corrupt.parquet").write_bytes(bytes(data))
    (base / "text.parquet").write_text("not parquet\n")
    (base / "afile").write_text("a file\n")

    # presets and training configs
    (base / "binary.yaml").write_bytes(b"\xff\xfe\x00garbage\x81")
    for name, text in {
        "bad_yaml.yaml": "world: {dt: [\n",
        "list.yaml": "- a\n- b\n",
        "scalar.yaml": "hello\n",
        "world5.yaml": "world: 5\n",
        "orca_list.yaml": "world: {orca: [1, 2]}\n",
        "policies_list.yaml": "policies: [orca, sarl]\n",
        "policy_5.yaml": "policies: {orca: 5}\n",
        "scen_str.yaml": "evaluation: {multi_human: random}\n",
        "dup.yaml": "evaluation: {multi_human: [random, random]}\n",
        "unknown_key.yaml": "world: {horizon: 3}\n",
        "dt_str.yaml": "world: {dt: fast}\n",
        "threads.yaml": "world: {threads: 100000}\n",
        "threads_neg.yaml": "world: {threads: -1}\n",
        "dt_tiny.yaml": "world: {dt: 1.0e-9}\n",
        "dt_zero.yaml": "world: {dt: 0}\n",
        "time_limit.yaml": "world: {time_limit: 1.0e9}\n",
        "cap.yaml": "evaluation: {continuation_cap: 1.0e9}\n",
        "train_split.yaml": "evaluation: {split: train}\n",  # episodes enough for the 4 GiB bound
        "vpref_nan.yaml": "robot: {v_pref: .nan}\n",
        "vpref_inf.yaml": "robot: {v_pref: .inf}\n",
        "humans.yaml": "evaluation: {n_humans: 100000}\n",
        "episodes_huge.yaml": f"evaluation: {{episodes: {10**30}}}\n",
        "crowdnav_dt.yaml": "name: crowdnav\nworld: {dt: 0.1}\nrobot: {v_pref: 1.0}\n",
        "unicycle.yaml": "name: uni\nworld: {kinematics: unicycle}\nrobot: {v_pref: 1.5}\n",
        "reward.yaml": "name: rew\nworld: {reward: {success_reward: 2.0}}\nrobot: {v_pref: 1.5}\n",
        "rl5.yaml": "rl: 5\n",
        "rl_list.yaml": "rl: [1, 2]\n",
        "il_neg.yaml": "imitation: {epochs: -1}\n",
        "train_key.yaml": "rl: {episodez: 3}\n",
        "lr_str.yaml": "rl: {lr: fast}\n",
    }.items():
        _yaml(base, name, text)

    # checkpoints
    from socialnav.policies.building import shipped_checkpoint

    shipped = shipped_checkpoint("sarl", "wang2022")
    shutil.copy(shipped, base / "sarl.pt")
    payload = torch.load(shipped, weights_only=True)
    (base / "empty.pt").write_bytes(b"")
    (base / "garbage.pt").write_bytes(bytes(range(256)) * 4)
    raw = shipped.read_bytes()
    (base / "truncated.pt").write_bytes(raw[: len(raw) // 2])
    torch.save({"format": payload["format"], "x": fractions.Fraction(1, 3)}, base / "pickle.pt")
    torch.save([1, 2, 3], base / "list.pt")

    def variant(name: str, **changes):
        p = dict(payload)
        for k, v in changes.items():
            if v is None:
                p.pop(k, None)
            else:
                p[k] = v
        torch.save(p, base / name)

    variant("no_state.pt", state_dict=None)
    variant("dim_str.pt", input_dim="13")
    variant("kwargs.pt", model_kwargs={"bogus": 1})
    bad_state = dict(payload["state_dict"])
    first_key = next(iter(bad_state))
    bad_state[first_key] = torch.zeros(3, 3, 3)
    variant("shapes.pt", state_dict=bad_state)
    variant("vp5.pt", config={**payload["config"], "value_policy": 5})
    variant(
        "vpkey.pt",
        config={**payload["config"], "value_policy": {**payload["config"]["value_policy"], "bogus": 1}},
    )
    variant(
        "vpval.pt",
        config={
            **payload["config"],
            "value_policy": {**payload["config"]["value_policy"], "information": "telepathy"},
        },
    )

    # output directories of earlier runs
    preset = load_preset("crowdnav")
    kw = dict(
        scenarios=["circle_crossing"],
        episodes=2,
        progress=False,
        workers=0,
        extra_manifest={"checkpoint": None},
    )  # as the command line records it
    run_protocol(make_policy("orca", safety_space=0.0), preset, base / "run_a", **kw)
    for name in ("run_a2", "run_bad_manifest", "run_foreign_name", "run_foreign_stamp", "run_corrupt"):
        shutil.copytree(base / "run_a", base / name)
    (base / "run_bad_manifest" / "manifest.json").write_text('{"preset": ')
    chunk = Path("episodes") / "circle_crossing__invisible" / "00000-00002.parquet"
    shutil.copy(base / "run_a" / chunk, base / "run_foreign_name" / chunk.with_name("00002-00004.parquet"))
    run_protocol(make_policy("orca", safety_space=0.3), preset, base / "run_other", **kw)
    shutil.copy(base / "run_other" / chunk, base / "run_foreign_stamp" / chunk)
    data = bytearray((base / "run_corrupt" / chunk).read_bytes())
    for i in range(64, 96):
        data[i] ^= 0xFF
    (base / "run_corrupt" / chunk).write_bytes(bytes(data))
    # training directories
    for name in ("t_garbage", "t_notstate", "t_locked"):
        (base / name).mkdir()
    (base / "t_garbage" / "last.pt").write_bytes(bytes(range(256)) * 4)
    shutil.copy(shipped, base / "t_notstate" / "last.pt")

    assert np.isfinite(len(trajs))
    locks = [DirectoryLock(base / "locked", "evaluation"), DirectoryLock(base / "t_locked", "training")]
    (base / "locked").mkdir()
    for lock in locks:
        lock.__enter__()

    class Held:
        def close(self) -> None:
            for lock in locks:
                lock.__exit__(None, None, None)

    return Held()
