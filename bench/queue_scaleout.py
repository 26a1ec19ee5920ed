#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
# Copyright (c) 2026 stlrefine authors
"""Queue mode figures (issue 20): submit -> runner start latency, throughput of N small jobs
with 1, 2, 3 worker replicas, recovery time of a killed worker's job; the embedded store for
comparison. Starts its own redis-server (unix socket, AOF) and stlrefined processes.

  bench/queue_scaleout.py BUILD_DIR [--jobs 100] [--levels 5]

Prints a Markdown table. Stdlib only.
"""
import argparse
import json
import os
import shutil
import signal
import struct
import subprocess
import tempfile
import time
import urllib.request


def octahedron():
    v = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    f = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    b = b"\0" * 80 + struct.pack("<I", len(f))
    for t in f:
        b += struct.pack("<3f", 0, 0, 0)
        for i in t:
            b += struct.pack("<3f", *[10 * c for c in v[i]])
        b += b"\0\0"
    return b


MESH = octahedron()


def split4(stl):
    # Each facet in four (midpoints): 32 facets, so that levels=8 makes 2 M faces.
    n = struct.unpack_from("<I", stl, 80)[0]
    out = []
    for k in range(n):
        c = [struct.unpack_from("<3f", stl, 84 + 50 * k + 12 + 12 * i) for i in range(3)]
        m = lambda a, b: tuple((x + y) / 2 for x, y in zip(a, b))
        ab, bc, ca = m(c[0], c[1]), m(c[1], c[2]), m(c[2], c[0])
        out += [(c[0], ab, ca), (ab, c[1], bc), (ca, bc, c[2]), (ab, bc, ca)]
    b = b"\0" * 80 + struct.pack("<I", len(out))
    for t in out:
        b += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *p) for p in t) + b"\0\0"
    return b


LONG_MESH = split4(MESH)


def http(method, url, body=None):
    req = urllib.request.Request(url, data=body, method=method)
    if body is not None:
        req.add_header("Content-Type", "model/stl")
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


class Stack:
    def __init__(self, build, tmp, queue):
        self.build, self.tmp, self.queue = build, tmp, queue
        self.procs, self.redis = [], None
        os.makedirs(f"{tmp}/data", exist_ok=True)

    def start_redis(self):
        sock = f"{self.tmp}/redis.sock"
        self.redis = subprocess.Popen(
            ["redis-server", "--port", "0", "--unixsocket", sock, "--dir", self.tmp,
             "--appendonly", "yes", "--save", "", "--maxmemory-policy", "noeviction"],
            stdout=subprocess.DEVNULL)
        while not os.path.exists(sock):
            time.sleep(0.01)
        time.sleep(0.1)
        return "unix://" + sock

    def daemon(self, name, extra, slots=1):
        argv = [f"{self.build}/bin/stlrefined", "--port", "0", "--data-dir", f"{self.tmp}/data",
                "--instance", name, "--compute-slots", str(slots), "--job-queue", "10000"] + extra
        if self.queue:
            argv += ["--queue", self.queue]
        p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        line = p.stdout.readline()
        port = int(line.rsplit(":", 1)[1])
        self.procs.append(p)
        return p, f"http://127.0.0.1:{port}"

    def stop(self):
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        if self.redis:
            self.redis.terminate()
            self.redis.wait()


def wait_done(base, ids, timeout=600):
    left, states = set(ids), {}
    end = time.time() + timeout
    while left and time.time() < end:
        for i in list(left):
            _, j = http("GET", f"{base}/v1/jobs/{i}")
            if j and j["state"] in ("done", "failed", "cancelled"):
                states[i] = j
                left.discard(i)
        if left:
            time.sleep(0.02)
    return states


def latency(base, n, query):
    # One job at a time on idle runners: started - created (the job's queued_seconds).
    lat = []
    for _ in range(n):
        _, j = http("POST", f"{base}/v1/jobs?{query}", MESH)
        j = wait_done(base, [j["id"]])[j["id"]]
        lat.append(j["timings"]["queued_seconds"] * 1000)
    lat.sort()
    return lat[len(lat) // 2], lat[int(len(lat) * 0.9)], max(lat)


def throughput(base, n, query):
    t0 = time.time()
    ids = [http("POST", f"{base}/v1/jobs?{query}", MESH)[1]["id"] for _ in range(n)]
    states = wait_done(base, ids)
    wall = time.time() - t0
    workers = {}
    for j in states.values():
        workers[j.get("worker", "-")] = workers.get(j.get("worker", "-"), 0) + 1
    done = sum(1 for j in states.values() if j["state"] == "done")
    return wall, done, workers


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--jobs", type=int, default=100)
    ap.add_argument("--levels", type=int, default=5)
    a = ap.parse_args()
    query = f"scheme=loop&levels={a.levels}"
    print("| setup | what | figure | load avg |")
    print("|---|---|---|---|", flush=True)

    class Rows:
        def append(self, row):
            print(row, flush=True)

    rows = Rows()
    load = lambda: "%.1f" % os.getloadavg()[0]

    # Embedded store: one daemon, its compute slots 1, 2, 3.
    for slots in (1, 2, 3):
        tmp = tempfile.mkdtemp(prefix="stlrefine-qbench-")
        s = Stack(a.build, tmp, None)
        try:
            _, base = s.daemon("embedded", [], slots)
            if slots == 1:
                med, p90, mx = latency(base, 30, query)
                rows.append(f"| embedded | submit -> start, median / p90 / max | {med:.1f} / {p90:.1f} / {mx:.1f} ms | {load()} |")
            wall, done, _ = throughput(base, a.jobs, query)
            rows.append(f"| embedded, 1 daemon, {slots} slot(s) | {a.jobs} jobs ({done} done) | {wall:.2f} s, {a.jobs / wall:.1f} jobs/s | {load()} |")
        finally:
            s.stop()
            shutil.rmtree(tmp, ignore_errors=True)

    # Queue mode: an api replica and 1, 2, 3 workers (1 compute slot each).
    for workers in (1, 2, 3):
        tmp = tempfile.mkdtemp(prefix="stlrefine-qbench-")
        s = Stack(a.build, tmp, None)
        try:
            s.queue = s.start_redis()
            _, api = s.daemon("api", ["--role", "api"])
            for w in range(workers):
                s.daemon(f"w{w + 1}", ["--role", "worker"])
            time.sleep(0.3)
            if workers == 1:
                med, p90, mx = latency(api, 30, query)
                rows.append(f"| queue (Redis) | submit -> start, median / p90 / max | {med:.1f} / {p90:.1f} / {mx:.1f} ms | {load()} |")
            wall, done, by = throughput(api, a.jobs, query)
            rows.append(f"| queue, api + {workers} worker(s) | {a.jobs} jobs ({done} done; {by}) | {wall:.2f} s, {a.jobs / wall:.1f} jobs/s | {load()} |")
        finally:
            s.stop()
            shutil.rmtree(tmp, ignore_errors=True)

    # Recovery: a worker killed mid-job; the other runs it again after the lease.
    for lease in (2, 5):
        tmp = tempfile.mkdtemp(prefix="stlrefine-qbench-")
        s = Stack(a.build, tmp, None)
        try:
            s.queue = s.start_redis()
            _, api = s.daemon("api", ["--role", "api"])
            procs = {}
            for w in ("w1", "w2"):
                procs[w], _ = s.daemon(w, ["--role", "worker", "--lease-seconds", str(lease)])
            time.sleep(0.3)
            long_query = "scheme=butterfly&levels=8"
            _, j = http("POST", f"{api}/v1/jobs?{long_query}", LONG_MESH)
            ref = wait_done(api, [j["id"]])[j["id"]]
            run = ref["timings"]["run_seconds"]
            _, j = http("POST", f"{api}/v1/jobs?{long_query}", LONG_MESH)
            jid = j["id"]
            end = time.time() + 60
            while time.time() < end:
                _, j = http("GET", f"{api}/v1/jobs/{jid}")
                if j["state"] == "running" and j.get("worker") and "level" in j["stage"]:
                    break
                time.sleep(0.01)
            else:
                raise RuntimeError("the job never ran")
            victim = j["worker"]
            t0 = time.time()
            procs[victim].kill()
            end = wait_done(api, [jid])[jid]
            total = time.time() - t0
            rows.append(f"| queue, worker killed mid-job, lease {lease} s | done on {end.get('worker')} (run alone {run:.2f} s) | {total:.2f} s from kill to done | {load()} |")
        finally:
            s.stop()
            shutil.rmtree(tmp, ignore_errors=True)



if __name__ == "__main__":
    main()
