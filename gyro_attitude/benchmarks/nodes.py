"""Node benchmark (``gyro-attitude bench --suite nodes``): how fast can sim → integrator go?

For each Imu rate, ``gyro_sim`` (real time, scene ``coning``) and ``attitude_integrator``
run as separate processes on loopback, as deployed (best-effort sensor-data QoS unless
``reliable``), for ``duration_s`` (60 s; 5 s in quick mode). Reported per rate:

* lost samples = published − integrated (the integrator's own ``accepted`` count from
  ``/diagnostics``, so losses of this probe do not count);
* how late the sim publishes a sample after its stamp (its due time), p50 / p99;
* latency from publish to attitude: ``received_timestamp`` of ``attitude`` at this probe
  minus ``source_timestamp`` (the sim's publish time, stamped by the middleware) of the
  ``imu/data_raw`` message with the same header stamp; p50 / p99 / max. Both timestamps
  come from the same system clock (one machine). The probe takes both topics serialized
  (``raw=True``) and reads the stamp from the CDR bytes, so it stays light next to the
  nodes it measures;
* CPU from the first sample on (start-up excluded): the integrator's share of one core and its
  CPU time per integrated sample (/proc), the simulator's share and the probe's own share.

Peers in the same run: ``executor:=single_threaded drain_queue:=false`` (plain rclpy, one
message per executor wakeup) at 2 kHz; in full runs ``executor:=single_threaded`` (rclpy's
executor, draining the queue per wakeup) at 4 and 8 kHz, against the default input thread.
The floor, in full runs at 4 and 8 kHz: ``benchmarks/relay_node.py`` in the integrator's place,
the same input thread and ``attitude`` output but no estimation: what no Python estimator node
can beat on the same machine and middleware.  ``GYRO_ATTITUDE_NODES_DURATION_S`` shortens
(or lengthens) the time per rate.

The highest rate with zero loss is the sustained rate. Everything shares the machine's
cores (sim, integrator, probe, and whatever else runs): quote figures with the conditions.
"""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

QUICK_RATES = (1000.0, 2000.0, 4000.0)
FULL_RATES = (500.0, 1000.0, 2000.0, 4000.0, 6000.0, 8000.0)
LATENCY_TARGET_P99_MS = 2.0
PEER_RATE_HZ = 2000.0  # the drain_queue:=false peer runs at this rate
# the single-threaded executor (draining) instead of the input thread, full runs only
SINGLE_THREADED_PEER_RATES_HZ = (4000.0, 8000.0)
# the relay node (the integrator's I/O, no estimation) in its place, full runs only
FLOOR_RATES_HZ = (4000.0, 8000.0)
_STAMP = struct.Struct("<iI")  # CDR (little endian): 4-byte encapsulation header, then stamp


def _stamp_of(cdr: bytes) -> int:
    sec, nanosec = _STAMP.unpack_from(cdr, 4)
    return sec * 1_000_000_000 + nanosec


def _cpu_s(pid: int) -> float | None:
    """CPU time (user + system, s) a running process has used so far, from /proc (None where
    there is no /proc or the process is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _env() -> dict[str, str]:
    from gyro_attitude.io.ament_prefix import node_environment

    return node_environment()


RELAY_COMMAND = (sys.executable, "-m", "gyro_attitude.benchmarks.relay_node")


def measure_rate(rate_hz: float, duration_s: float, env: dict[str, str],
                 reliability: str = "best_effort", scene: str = "coning",
                 integrator_params: tuple[str, ...] = (),
                 integrator_command: tuple[str, ...] | None = None) -> dict:
    """Run sim + integrator at ``rate_hz`` for ``duration_s``; return one result row.
    ``integrator_command``: another node in the integrator's place (the relay floor)."""
    import threading

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.context import Context
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu

    from gyro_attitude.io.ament_prefix import node_command
    from gyro_attitude.ros.input_thread import InputThread
    from gyro_attitude.ros.qos import imu_qos

    ns = f"/bench_nodes_{os.getpid()}_{int(rate_hz)}"
    context = Context()
    rclpy.init(context=context, domain_id=int(env["ROS_DOMAIN_ID"]))
    node = rclpy.create_node("bench_probe", namespace=ns, context=context)
    # the probe takes its topics as the integrator does (one thread, its own wait set): an
    # executor would cost it more CPU per message than the nodes it measures
    inputs = InputThread(context, threading.Lock(), name="bench probe inputs")

    def subscribe(msg_type, topic, callback, qos, raw=False, with_info=False):
        sub = node.create_subscription(msg_type, topic, callback, qos, raw=raw,
                                       callback_group=inputs.group)
        inputs.add(sub, callback, with_info=with_info)
    published_at: dict[int, int] = {}
    received_at: dict[int, int] = {}
    accepted = [0]
    published_total = [0]

    cpu_at_first = {}  # the integrator's and the probe's CPU time when the first sample came

    def on_imu(cdr, info):
        published_at[_stamp_of(cdr)] = info["source_timestamp"]
        if not cpu_at_first:
            cpu_at_first.update(integrator=_cpu_s(integ.pid), sim=_cpu_s(sim.pid),
                                probe=time.process_time(), wall=time.monotonic())

    def on_att(cdr, info):
        received_at[_stamp_of(cdr)] = info["received_timestamp"]

    def on_diag(msg):
        for s in msg.status:
            for kv in s.values:
                if kv.key == "accepted":
                    accepted[0] = int(kv.value)

    subscribe(Imu, f"{ns}/imu/data_raw", on_imu, imu_qos("best_effort", 50000), raw=True,
              with_info=True)
    subscribe(QuaternionStamped, f"{ns}/attitude", on_att,
              QoSProfile(depth=50000, reliability=ReliabilityPolicy.RELIABLE), raw=True,
              with_info=True)
    common = ["--ros-args", "-r", f"__ns:={ns}", "-p", f"qos_reliability:={reliability}"]
    integ_args = common + ["-p", "diagnostics_period_s:=0.25",
                           "-r", f"/diagnostics:={ns}/diagnostics"]
    subscribe(DiagnosticArray, f"{ns}/diagnostics", on_diag, 50)
    for assignment in integrator_params:
        integ_args += ["-p", assignment]
    # the nodes' output goes to files, read after: a pipe nobody reads while they run fills
    # (64 KiB) and then blocks the node that writes to it, which the latency would measure
    integ_log = tempfile.TemporaryFile("w+")
    sim_log = tempfile.TemporaryFile("w+")
    command = list(integrator_command or node_command("attitude_integrator"))
    integ = subprocess.Popen(command + integ_args, env=env,
                             stdout=subprocess.DEVNULL, stderr=integ_log, text=True,
                             start_new_session=True)
    sim = subprocess.Popen(
        node_command("gyro_sim") + common + [
            "-p", f"scene:={scene}", "-p", f"rate_hz:={rate_hz!r}",
            "-p", f"duration_s:={duration_s!r}", "-p", "wait_for_subscribers:=2",
            "-p", "wait_timeout_s:=30.0", "-p", "publish_truth:=false"],
        env=env, stdout=sim_log, stderr=subprocess.STDOUT, text=True,
        start_new_session=True)
    inputs.start()  # after both processes exist (the first Imu reads their CPU time)
    n_expected = int(round(rate_hz * duration_s))
    cpu_at_end: dict = {}
    try:
        deadline = time.monotonic() + duration_s * 2 + 60
        sim_seen = None  # (CPU, wall) of the simulator when last seen running: /proc has
        #                  nothing of it once it has exited and been reaped
        while sim.poll() is None and time.monotonic() < deadline and inputs.running:
            if cpu_at_first and (sim_cpu := _cpu_s(sim.pid)) is not None:
                sim_seen = (sim_cpu, time.monotonic())
            time.sleep(0.1)
        time.sleep(1.0)  # late attitudes and the last diagnostics
        cpu_at_end = {"integrator": _cpu_s(integ.pid), "probe": time.process_time(),
                      "wall": time.monotonic(), "sim": sim_seen}
        sim_log.seek(0)
        for line in sim_log.read().splitlines():
            if "published" in line and "samples" in line:
                published_total[0] = int(line.split("published")[1].split()[0])
    finally:
        for p in (sim, integ):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()
        inputs.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
        integ_log.seek(0)
        integ_tail = integ_log.read().splitlines()[-5:]
        sim_log.close()
        integ_log.close()
    if inputs.failure is not None:  # the probe's own failure, not the nodes'
        raise inputs.failure

    pairs = [received_at[s] - published_at[s] for s in received_at if s in published_at]
    # where losses happened (sample index from the first stamp seen by the probe)
    stamps = sorted(published_at)
    missing = [i for i, s in enumerate(stamps) if s not in received_at]
    lat = np.array(pairs, dtype=np.float64) * 1e-6  # ms
    # how late the sim publishes each sample after its stamp (real time: stamp = the
    # sample's due time on the wall clock, so this is the timer's lateness, not drift)
    late = np.array([published_at[s] - s for s in published_at], dtype=np.float64) * 1e-6
    published = published_total[0] or n_expected
    # CPU shares from the first sample on (start-up excluded): who used the two cores
    cpu = {}
    if cpu_at_first and cpu_at_first["integrator"] is not None and \
            cpu_at_end.get("integrator") is not None:
        wall = cpu_at_end["wall"] - cpu_at_first["wall"]
        integ_cpu = cpu_at_end["integrator"] - cpu_at_first["integrator"]
        cpu = {"integrator_cpu_share": integ_cpu / wall,
               "integrator_cpu_us_per_sample": integ_cpu / max(accepted[0], 1) * 1e6,
               "probe_cpu_share": (cpu_at_end["probe"] - cpu_at_first["probe"]) / wall}
        if cpu_at_first.get("sim") is not None and cpu_at_end["sim"] is not None:
            sim_cpu, sim_wall = cpu_at_end["sim"]
            cpu["sim_cpu_share"] = ((sim_cpu - cpu_at_first["sim"])
                                    / max(sim_wall - cpu_at_first["wall"], 1e-9))
    return {
        "suite": "nodes",
        "scene": scene,
        "rate_hz": rate_hz,
        "duration_s": duration_s,
        "qos": reliability,
        "integrator_params": list(integrator_params),
        "node": "relay (I/O only)" if integrator_command else "attitude_integrator",
        "published": published,
        "integrated": accepted[0],
        "lost": published - accepted[0],
        "attitudes_at_probe": len(received_at),
        "missing_at_probe_first_index": missing[0] if missing else None,
        "missing_at_probe_last_index": missing[-1] if missing else None,
        "latency_pairs": len(pairs),
        "latency_p50_ms": float(np.percentile(lat, 50)) if lat.size else None,
        "latency_p99_ms": float(np.percentile(lat, 99)) if lat.size else None,
        "latency_max_ms": float(lat.max()) if lat.size else None,
        "sim_late_p50_ms": float(np.percentile(late, 50)) if late.size else None,
        "sim_late_p99_ms": float(np.percentile(late, 99)) if late.size else None,
        "cpu_count": os.cpu_count(),
        **cpu,
        # what the integrator said last, where it integrated nothing (why is then the question)
        "integrator_log_tail": integ_tail if accepted[0] == 0 else [],
    }


def run(quick: bool, out_dir: Path) -> list[dict]:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    env = _env()
    duration = 5.0 if quick else 60.0
    if os.environ.get("GYRO_ATTITUDE_NODES_DURATION_S"):
        duration = float(os.environ["GYRO_ATTITUDE_NODES_DURATION_S"])
    rates = QUICK_RATES if quick else FULL_RATES
    rows = []
    print(f"nodes: gyro_sim -> attitude_integrator, {duration:g} s per rate, "
          f"{os.cpu_count()} cores (shared), ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}")
    print(f"{'rate Hz':>9} {'published':>10} {'integrated':>10} {'lost':>6} "
          f"{'p50 ms':>8} {'p99 ms':>8} {'max ms':>8} {'integ CPU':>9} {'µs/sample':>9} "
          f"{'probe CPU':>9} {'sim CPU':>9}")

    def fmt(x):
        return f"{x:8.3f}" if x is not None else f"{'-':>8}"

    def cpu(row):
        if "integrator_cpu_share" not in row:
            return f"{'-':>9} {'-':>9} {'-':>9} {'-':>9}"
        sim = row.get("sim_cpu_share")
        return (f"{row['integrator_cpu_share']:9.0%} {row['integrator_cpu_us_per_sample']:9.1f} "
                f"{row['probe_cpu_share']:9.0%} " + (f"{sim:9.0%}" if sim is not None
                                                     else f"{'-':>9}"))

    for rate in rates:
        row = measure_rate(rate, duration, env)
        rows.append(row)
        print(f"{rate:9.0f} {row['published']:10d} {row['integrated']:10d} {row['lost']:6d} "
              f"{fmt(row['latency_p50_ms'])} {fmt(row['latency_p99_ms'])} "
              f"{fmt(row['latency_max_ms'])} {cpu(row)}", flush=True)
    # peer in the same run: the integrator without draining its queue per wakeup (plain
    # rclpy, one message per executor iteration), at the rate where the difference shows
    peer_rate = PEER_RATE_HZ
    main_rows = list(rows)
    peers = [(peer_rate, ("executor:=single_threaded", "drain_queue:=false"),
              "executor:=input_thread (default)")]
    peers += [(rate, ("executor:=single_threaded",), "executor:=input_thread (default)")
              for rate in (SINGLE_THREADED_PEER_RATES_HZ if not quick else ())]
    # the floor: a node with the integrator's I/O and no estimation (benchmarks/relay_node.py)
    floor_rates = () if quick else FLOOR_RATES_HZ
    peers += [(rate, (), "the floor: I/O only") for rate in floor_rates]
    for rate, params, of in peers:
        relay = of.startswith("the floor")
        peer = measure_rate(rate, duration, env, integrator_params=params,
                            integrator_command=RELAY_COMMAND if relay else None)
        peer["peer_of"] = of
        peer["integrator_params"] = list(params)
        rows.append(peer)
        print(f"{rate:9.0f} {peer['published']:10d} {peer['integrated']:10d} "
              f"{peer['lost']:6d} {fmt(peer['latency_p50_ms'])} {fmt(peer['latency_p99_ms'])} "
              f"{fmt(peer['latency_max_ms'])} {cpu(peer)}   <- "
              + ("floor: relay node, I/O only" if relay else f"peer: {' '.join(params)}"),
              flush=True)
    ok = [r["rate_hz"] for r in main_rows if r["lost"] == 0]
    best = max(ok) if ok else None
    fast = [r["rate_hz"] for r in main_rows if r["lost"] == 0
            and r["latency_p99_ms"] is not None
            and r["latency_p99_ms"] < LATENCY_TARGET_P99_MS]
    best_fast = max(fast) if fast else None
    summary = {"suite": "nodes", "summary": True, "duration_s": duration,
               "max_rate_no_loss_hz": best,
               "max_rate_no_loss_p99_under_target_hz": best_fast,
               "latency_target_p99_ms": LATENCY_TARGET_P99_MS, "rates_tested": list(rates)}
    rows.append(summary)
    print(f"highest rate with zero loss over {duration:g} s: "
          f"{best if best is not None else 'none'} Hz; with zero loss and p99 < "
          f"{LATENCY_TARGET_P99_MS:g} ms: {best_fast if best_fast is not None else 'none'} Hz "
          f"(rates tried: {list(rates)})")
    (out_dir / "nodes.json").write_text(json.dumps(rows, indent=2))
    return rows


if __name__ == "__main__":  # python -m gyro_attitude.benchmarks.nodes [--quick]
    sys.exit(0 if run("--quick" in sys.argv, Path("bench_out")) else 1)
