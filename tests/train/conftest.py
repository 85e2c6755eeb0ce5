import pytest
import yaml

pytest.importorskip("torch")


@pytest.fixture()
def quick_preset(tmp_path):
    """crowdnav with a 6 s time limit and 3 humans: untrained policies time out quickly."""
    from importlib import resources

    data = yaml.safe_load((resources.files("socialnav.configs") / "crowdnav.yaml").read_text())
    data["name"] = "crowdnav_quick"
    data["world"]["time_limit"] = 6.0
    data["training"]["n_humans"] = 3
    p = tmp_path / "crowdnav_quick.yaml"
    p.write_text(yaml.safe_dump(data))
    return str(p)

