"""What the ULog check scripts (check_ulog.py: the host's flight.ulg; check_onboard_ulog.py: the
firmware's onboard log) share: reading a log with pyulog (and its ulog_info CLI) and checking that
the topics and fields a script needs are there.
"""
import subprocess
import sys

from pyulog import ULog


def load(path):
    """The ULog at `path` and its topics (name -> field -> values); ulog_info must read it too."""
    subprocess.run([sys.executable, "-m", "pyulog.info", path], check=True, stdout=subprocess.DEVNULL)
    u = ULog(path)
    return u, {d.name: d.data for d in u.data_list}


def require_fields(topics, need):
    """Exit 1 naming what is missing when a topic or field of `need` (topic -> fields) is absent."""
    errors = []
    for t, fields in need.items():
        if t not in topics:
            errors.append(f"topic {t} missing (have {sorted(topics)})")
            continue
        for f in fields:
            if f not in topics[t]:
                errors.append(f"{t}.{f} missing")
    if errors:
        print("\n".join(errors))
        sys.exit(1)
