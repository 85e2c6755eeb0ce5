"""Runs many `socialnav` command lines, each in its own process, from one interpreter start.

Usage: ``python forkrun.py CASES.json RESULTS.json``. CASES is a list of ``{"argv", "cwd", "stdout",
"stderr", "fsize"}``. The heavy imports (torch, pyarrow, the CLI) are done once here; each case then
runs ``socialnav.cli.main`` in a forked child with its stdout/stderr sent to files, and exits with
main's return code (an uncaught exception prints its traceback and exits 99, as the interpreter
would print one). RESULTS is the list of exit codes. Starting one interpreter per case would cost
~0.4 s (2.5 s with torch) each on a busy machine; a fork costs milliseconds.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import sys
import traceback


def run_case(case: dict) -> int:
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # child
        code = 99
        try:
            os.chdir(case["cwd"])
            for fd, name in ((1, case["stdout"]), (2, case["stderr"])):
                target = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
                os.dup2(target, fd)
                os.close(target)
            if case.get("fsize") is not None:  # a "full disk": writes beyond fsize bytes fail (EFBIG)
                signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
                resource.setrlimit(resource.RLIMIT_FSIZE, (case["fsize"], case["fsize"]))
            from socialnav.cli import main

            code = main(case["argv"])
        except SystemExit as exc:  # argparse errors
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException:
            traceback.print_exc()
            code = 99
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status)


def main() -> None:
    cases = json.loads(open(sys.argv[1]).read())
    import pyarrow.parquet  # noqa: F401
    import torch  # noqa: F401

    import socialnav.cli  # noqa: F401
    import socialnav.evaluate.runner  # noqa: F401
    import socialnav.policies.learned  # noqa: F401
    import socialnav.train.value.trainer  # noqa: F401

    codes = [run_case(case) for case in cases]
    with open(sys.argv[2], "w") as f:
        json.dump(codes, f)


if __name__ == "__main__":
    main()
