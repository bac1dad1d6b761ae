"""Runs `baker` as a child process and reads what it printed.

In: a command line. Out: a dict with the exit status, wall time, the child's
peak resident memory (ru_maxrss from wait4 in a small launcher process, KiB
on Linux: the baker process alone), the load average before and after, and the parsed
timing table ("stage  ms  note" rows, bk_timings_print in base/common.c),
the photon summary line of `baker bake` and the ray-step note of `baker view`.
A run that fails, crashes or times out is recorded (status "failed" or
"timeout", the tail of its stderr) and never raises.
"""
import json
import os
import re
import signal
import subprocess
import sys
import time

# "%-24s %12.1f  %s": a name, a number with one decimal, an optional note
_ROW = re.compile(r"^(\S.*?)\s+(-?\d+\.\d)(?:\s\s(.*))?$")
_PHOTONS = re.compile(r"^photons: (\d+) traced, (\d+) missed the grid, (\d+) left it, "
                      r"(\d+) absorbed, (\d+) stopped at the step limit")
_RAY_STEPS = re.compile(r"(\d+) ray-steps")


def parse_timings(stdout):
    """Rows of the timing table after its "stage  ms" header, in order:
    [(name, ms, note)], the "total" row included."""
    rows = []
    in_table = False
    for line in stdout.splitlines():
        if re.match(r"^stage\s+ms\s*$", line):
            in_table = True
            rows = []  # a frame range prints one table per frame: keep the last
            continue
        if not in_table:
            continue
        m = _ROW.match(line.rstrip())
        if not m:
            in_table = False
            continue
        rows.append((m.group(1).strip(), float(m.group(2)), (m.group(3) or "").strip()))
    return rows


def parse_photon_summary(stdout):
    for line in stdout.splitlines():
        m = _PHOTONS.match(line)
        if m:
            keys = ("traced", "missed_grid", "left_grid", "absorbed", "step_limit")
            return dict(zip(keys, (int(g) for g in m.groups())))
    return None


def parse_ray_steps(note):
    m = _RAY_STEPS.search(note or "")
    return int(m.group(1)) if m else None


def loadavg():
    try:
        return list(os.getloadavg())
    except OSError:
        return None


# The child is started by a fresh, small Python that forks it and reports its
# rusage: on Linux a child's ru_maxrss starts from its parent's RSS at fork
# (the hiwater mark survives exec), so measured straight from this process,
# which holds grids of hundreds of MB, a small bake would read as that large.
_LAUNCHER = r"""
import json, os, sys
out, argv = sys.argv[1], sys.argv[2:]
pid = os.fork()
if pid == 0:
    try:
        os.execv(argv[0], argv)
    except OSError as e:
        sys.stderr.write("bench: cannot run %s: %s\n" % (argv[0], e))
        os._exit(127)
_, status, ru = os.wait4(pid, 0)
with open(out, "w") as f:
    json.dump({"maxrss_kib": ru.ru_maxrss, "utime": ru.ru_utime, "stime": ru.ru_stime,
               "exit": os.waitstatus_to_exitcode(status)}, f)
code = os.waitstatus_to_exitcode(status)
sys.exit(code if code >= 0 else 128 - code)
"""


def run(cmd, log_prefix, timeout_s, env=None, cwd=None):
    """Runs cmd (cmd[0] a path) with stdout/stderr to log_prefix.out/.err, in
    folder cwd when given; returns the record."""
    rec = {"cmd": [str(c) for c in cmd], "load_before": loadavg()}
    out_path, err_path, ru_path = log_prefix + ".out", log_prefix + ".err", log_prefix + ".rusage"
    t0 = time.monotonic()
    try:
        with open(out_path, "w") as out, open(err_path, "w") as err:
            proc = subprocess.Popen([sys.executable, "-S", "-c", _LAUNCHER, ru_path] + rec["cmd"],
                                    stdout=out, stderr=err, env=env, cwd=cwd,
                                    start_new_session=True)
    except OSError as e:
        rec.update(status="failed", rc=None, error=f"could not start: {e}", wall_s=0.0)
        return rec
    timed_out = False
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        timed_out = True
        os.killpg(proc.pid, signal.SIGKILL)  # its own session: the launcher and baker, nothing else
        proc.wait()
    rec["wall_s"] = time.monotonic() - t0
    rec["load_after"] = loadavg()
    usage = None
    try:
        with open(ru_path) as f:
            usage = json.load(f)
    except (OSError, ValueError):
        pass
    rc = usage["exit"] if usage else proc.returncode
    rec["rc"] = rc
    rec["max_rss_mib"] = usage["maxrss_kib"] / 1024.0 if usage else None
    rec["cpu_s"] = usage["utime"] + usage["stime"] if usage else None
    with open(out_path, errors="replace") as f:
        stdout = f.read()
    with open(err_path, errors="replace") as f:
        stderr = f.read()
    # `bake` prints its table on stdout, `view` on stderr
    rows = parse_timings(stdout) or parse_timings(stderr)
    rec["stages"] = [{"name": n, "ms": ms, "note": note} for n, ms, note in rows]
    rec["photon_summary"] = parse_photon_summary(stdout)
    if timed_out:
        rec["status"] = "timeout"
        rec["error"] = f"killed after {timeout_s:g} s"
    elif rc != 0:
        rec["status"] = "failed"
        if rc < 0:
            rec["error"] = f"killed by signal {-rc}"
        else:
            tail = [l for l in stderr.strip().splitlines() if l.strip()][-3:]
            rec["error"] = " | ".join(tail) or f"exit status {rc}"
    else:
        rec["status"] = "ok"
        if parse_timings(stdout):  # a bake: stderr holds only warnings
            warn = [l for l in stderr.splitlines() if l.strip()]
            if warn:
                rec["stderr_tail"] = warn[-3:]
    return rec


def stage_ms(rec, name):
    for s in rec.get("stages") or []:
        if s["name"] == name:
            return s["ms"]
    return None


def stage_note(rec, name):
    for s in rec.get("stages") or []:
        if s["name"] == name:
            return s["note"]
    return None
