"""``train(on_validation=...)``: called after every validation (episode 0: the one after imitation);
True stops the run there with ``last.pt`` written, so that the same call resumes it."""

import torch

from socialnav.train.value.settings import load_train_settings
from socialnav.train.value.trainer import train

from .test_trainer import TINY


def _settings(tmp_path):
    p = tmp_path / "tiny.yaml"
    p.write_text(TINY)
    return load_train_settings(p)


def test_stop_after_imitation_then_resume(tmp_path, quick_preset):
    seen = []

    def stop_at_once(episode, val, wall_time):
        seen.append((episode, val["episode"], wall_time > 0))
        return True

    out = tmp_path / "run"
    first = train("sarl", quick_preset, out, _settings(tmp_path), progress=False, on_validation=stop_at_once)
    assert seen == [(0, 0, True)]
    assert not first.finished and first.episodes == 0 and first.gradient_steps == 0
    saved = torch.load(out / "last.pt", weights_only=True)["extra"]["resume"]
    assert saved["episode"] == 0 and (out / "best.pt").exists()
    second = train("sarl", quick_preset, out, _settings(tmp_path), progress=False)
    assert second.resumed and second.finished and second.episodes == 24


def test_stop_at_the_first_rl_validation(tmp_path, quick_preset):
    seen = []

    def stop_in_rl(episode, val, wall_time):
        seen.append(episode)
        return episode > 0

    out = tmp_path / "run"
    result = train(
        "sarl", quick_preset, out, _settings(tmp_path), progress=False, on_validation=stop_in_rl
    )
    # validate_every 12: the first RL validation falls on the first step that reaches 12 episodes
    assert seen[0] == 0 and len(seen) == 2 and 12 <= seen[1] < 24
    assert not result.finished and result.episodes == seen[1] and result.last_val["episode"] == seen[1]
    saved = torch.load(out / "last.pt", weights_only=True)["extra"]["resume"]
    assert saved["episode"] == seen[1] and saved["last_val"]["episode"] == seen[1]
