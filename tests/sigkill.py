"""Kill a studyapp subprocess with SIGKILL at a random moment of its session (the kill tests' one helper)."""

import os
import signal
import subprocess
import time


def start_and_kill(cmd, cwd, env, rng, max_delay_s: float) -> tuple[bool, int]:
    """Start ``cmd``, wait for its "session ... started" line, sleep up to ``max_delay_s`` (uniform, from
    ``rng``) and SIGKILL it if it still runs. Returns (killed, return code)."""
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    if "started" in line:
        time.sleep(rng.uniform(0.0, max_delay_s))
    killed = proc.poll() is None
    if killed:
        os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stdout.close()
    proc.stderr.close()
    return killed, proc.returncode
