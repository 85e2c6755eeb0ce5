"""A small walled preset for training tests."""

import yaml


def write_walled_preset(tmp_path, name: str, scenarios: list[str]) -> str:
    """francis2023 trained and evaluated on ``scenarios`` only, with a 10 s time limit; its path."""
    from importlib import resources

    data = yaml.safe_load((resources.files("socialnav.configs") / "francis2023.yaml").read_text())
    data["name"] = name
    data["world"]["time_limit"] = 10.0
    data["training"]["scenarios"] = scenarios
    data["evaluation"]["multi_human"] = scenarios
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(data))
    return str(p)
