"""Training: an interrupted imitation resumes at its next epoch with its demonstrations kept,
``rl.episodes`` is met exactly, and the shipped smoke-test config loads and runs."""

import json

import pytest
import torch
import yaml

import socialnav.train.value.imitation_phase as imitation_phase
from socialnav.policies.learned import load_checkpoint
from socialnav.settings import ConfigError
from socialnav.train.settings_files import shipped_train_configs
from socialnav.train.value.settings import load_train_settings
from socialnav.train.value.trainer import train

SETTINGS = """\
collection_batch: 8
threads: 1
checkpoint_every: 8
log_every: 4
imitation: {episodes: 8, epochs: 6}
rl: {episodes: 10, validate_every: 10, val_episodes: 4, target_update_every: 8, warmup_transitions: 50,
     gradient_steps_per_episode: 1, epsilon_decay_episodes: 8}
"""


def _preset(tmp_path, time_limit):
    from importlib import resources

    data = yaml.safe_load((resources.files("socialnav.configs") / "crowdnav.yaml").read_text())
    data["name"] = "crowdnav_quick"
    data["world"]["time_limit"] = time_limit
    data["training"]["n_humans"] = 3
    p = tmp_path / "crowdnav_quick.yaml"
    p.write_text(yaml.safe_dump(data))
    return str(p)


@pytest.fixture()
def quick_preset(tmp_path):
    """crowdnav with 3 humans and a 10 s limit: the ORCA teacher arrives (8 m at 1 m/s)."""
    return _preset(tmp_path, 10.0)


@pytest.fixture()
def settings(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(SETTINGS)
    return load_train_settings(p)


class Interrupt(BaseException):
    pass


def _interrupt_fit_after(monkeypatch, epochs: int, collected: list):
    """Makes the imitation's progress bar raise after ``epochs`` epochs (the state of each epoch is
    saved before its bar ticks), as a kill at that moment would."""
    real = imitation_phase.progress_bar

    def progress(total, initial, *, desc, enabled):
        bar = real(total, initial, desc=desc, enabled=False)
        if "imitation: fit" in desc:
            update = bar.update

            def tick(k=1):
                update(k)
                collected.append(k)
                if initial + len(collected) >= epochs:
                    raise Interrupt

            bar.update = tick
        return bar

    monkeypatch.setattr(imitation_phase, "progress_bar", progress)


def test_interrupted_imitation_resumes_at_the_next_epoch_with_the_same_result(
    tmp_path, quick_preset, settings, monkeypatch
):
    reference = train("sarl", quick_preset, tmp_path / "ref", settings, progress=False, log=lambda s: None)
    assert reference.episodes == 10  # rl.episodes met exactly, not rounded up to whole lockstep steps

    ticks: list = []
    _interrupt_fit_after(monkeypatch, 3, ticks)
    run = tmp_path / "run"
    with pytest.raises(Interrupt):
        train("sarl", quick_preset, run, settings, progress=False, log=lambda s: None)
    assert (run / "il_demos.npz").exists() and (run / "il_state.pt").exists() and not (run / "il.pt").exists()
    state = load_checkpoint(run / "il_state.pt", "sarl")
    assert len(state.extra["il_losses"]) == 3

    monkeypatch.undo()
    lines: list[str] = []
    import socialnav.train.value.imitation as imitation

    def no_collection(*a, **k):
        raise AssertionError("the demonstrations were collected again")

    monkeypatch.setattr(imitation, "collect_demonstrations", no_collection)
    resumed = train("sarl", quick_preset, run, settings, progress=False, log=lines.append)
    assert any("resuming at epoch 3 of 6" in line for line in lines), lines
    assert not (run / "il_state.pt").exists() and not (run / "il_demos.npz").exists()
    ref_il = load_checkpoint(tmp_path / "ref" / "il.pt", "sarl")
    run_il = load_checkpoint(run / "il.pt", "sarl")
    assert run_il.extra["il_losses"] == ref_il.extra["il_losses"] and len(run_il.extra["il_losses"]) == 6
    for key, value in ref_il.model.state_dict().items():
        torch.testing.assert_close(run_il.model.state_dict()[key], value, rtol=0, atol=0)
    assert resumed.episodes == 10
    assert resumed.resumed and not reference.resumed  # continued from the interrupted imitation's files


def test_imitation_resume_refuses_other_settings(tmp_path, quick_preset, settings, monkeypatch):
    import dataclasses

    _interrupt_fit_after(monkeypatch, 1, [])
    with pytest.raises(Interrupt):
        train("sarl", quick_preset, tmp_path, settings, progress=False, log=lambda s: None)
    monkeypatch.undo()
    other = dataclasses.replace(settings, imitation=dataclasses.replace(settings.imitation, lr=0.01))
    with pytest.raises(ConfigError, match="imitation.lr"):
        train("sarl", quick_preset, tmp_path, other, progress=False, log=lambda s: None)


def test_rl_episodes_is_met_exactly_when_many_episodes_end_together(tmp_path, settings):
    import dataclasses

    quick_preset = _preset(tmp_path, 6.0)  # nobody arrives: all 16 slots time out in the same step
    s = dataclasses.replace(settings, collection_batch=16, imitation=dataclasses.replace(settings.imitation,
                            epochs=0), rl=dataclasses.replace(settings.rl, episodes=13, validate_every=100))
    result = train("sarl", quick_preset, tmp_path, s, progress=False, log=lambda s: None)
    assert result.episodes == 13
    assert load_checkpoint(tmp_path / "last.pt", "sarl").extra["resume"]["episode"] == 13
    rows = (tmp_path / "curves.csv").read_text().splitlines()
    assert max(int(r.split(",")[1]) for r in rows[1:]) == 13


def test_smoke_config_is_shipped_and_loads_by_name():
    assert "smoke" in shipped_train_configs()
    smoke = load_train_settings("smoke")
    assert smoke.rl.episodes == 64 and smoke.imitation.epochs == 5
    with pytest.raises(ConfigError, match=r"shipped configs: (\w+, )*smoke"):
        load_train_settings("smokey")


@pytest.mark.slow
def test_smoke_config_trains_end_to_end(tmp_path, capsys):
    from socialnav.cli import main

    assert main(["train", "--policy", "sarl", "--preset", "crowdnav", "--config", "smoke", "--out",
                 str(tmp_path), "--no-progress"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["episodes"] == 64
    for name in ("il.pt", "best.pt", "last.pt", "curves.csv"):
        assert (tmp_path / name).exists()
