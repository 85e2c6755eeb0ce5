"""The metrics and the simulator must be usable without PyTorch (it is an optional extra)."""

import subprocess
import sys


def test_metrics_simulator_and_protocol_do_not_import_torch():
    code = (
        "import sys\n"
        "import socialnav.metrics, socialnav.trajectory, socialnav.sim.world, socialnav.envs.single\n"
        "import socialnav.evaluate.runner, socialnav.policies, socialnav.cli\n"
        "socialnav.policies.list_policies()\n"
        "assert 'torch' not in sys.modules, 'torch was imported'\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
