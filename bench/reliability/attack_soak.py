#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
# Copyright (c) 2026 stlrefine authors
"""The attacks of issue 16 against a running stlrefined, with figures (run by hand).

    build/bin/stlrefined --port 8099 --data-dir /tmp/soak --memory-budget 1G &
    bench/reliability/attack_soak.py --port 8099 --seconds 30

Each phase prints what a bureau's monitoring would see while the attack runs: /healthz and
/v1/info latency percentiles and failures, and the memory the daemon has reserved
(stlrefine_memory_reserved_bytes from /metrics). Standard library only.
"""
import argparse
import contextlib
import os
import random
import socket
import statistics
import struct
import threading
import time


def tetra_stl():
    # An octahedron, 8 facets, binary STL (the attack suite's small body).
    v = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    out = bytearray(80) + struct.pack("<I", len(faces))
    for f in faces:
        out += struct.pack("<3f", 0, 0, 0)
        for i in f:
            out += struct.pack("<3f", *v[i])
        out += b"\0\0"
    return bytes(out)


def request(port, raw, timeout=10.0):
    """Sends raw, returns (status, body bytes, seconds); status 0 on a socket error."""
    start = time.monotonic()
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall(raw)
            data = b""
            while True:
                chunk = s.recv(1 << 16)
                if not chunk:
                    break
                data += chunk
        status = int(data.split(b" ", 2)[1]) if data.startswith(b"HTTP/1.1 ") else 0
        body = data.split(b"\r\n\r\n", 1)[1] if b"\r\n\r\n" in data else b""
        return status, body, time.monotonic() - start
    except OSError:
        return 0, b"", time.monotonic() - start


def post(path, body):
    return (f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
            f"Content-Length: {len(body)}\r\n\r\n").encode() + body


def reserved_bytes(port):
    _, body, _ = request(port, b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")
    for line in body.decode(errors="replace").splitlines():
        if line.startswith("stlrefine_memory_reserved_bytes"):
            return int(float(line.split()[-1]))
    return -1


def probe(port, seconds, label):
    """/healthz and /v1/info every 100 ms while an attack runs."""
    stl = tetra_stl()
    health, info, peak_reserved = [], [], 0
    health_status, info_status = {}, {}
    until = time.monotonic() + seconds
    while time.monotonic() < until:
        status, _, t = request(port, b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        health.append(t * 1000)
        health_status[status] = health_status.get(status, 0) + 1
        status, _, t = request(port, post("/v1/info", stl))
        info.append(t * 1000)
        info_status[status] = info_status.get(status, 0) + 1
        peak_reserved = max(peak_reserved, reserved_bytes(port))
        time.sleep(0.1)

    def pct(xs, p):
        xs = sorted(xs)
        return xs[min(len(xs) - 1, int(p / 100 * len(xs)))]

    print(f"[{label}] {len(health)} rounds: /healthz p50 {pct(health, 50):.2f} ms "
          f"p99 {pct(health, 99):.2f} ms; /v1/info p50 {pct(info, 50):.2f} ms "
          f"p99 {pct(info, 99):.2f} ms; statuses /healthz {health_status} /v1/info "
          f"{info_status}; memory reserved at most "
          f"{peak_reserved / 2**20:.1f} MiB", flush=True)


@contextlib.contextmanager
def trickling(pick, period):
    """While the block runs, sends one byte to each socket pick() returns, every period s."""
    stop = threading.Event()

    def trickle():
        while not stop.is_set():
            for s in pick():
                try:
                    s.send(b"x")
                except OSError:
                    pass
            stop.wait(period)

    t = threading.Thread(target=trickle)
    t.start()
    try:
        yield
    finally:
        stop.set()
        t.join()


def slow_uploads(port, seconds, count=50):
    socks = []
    for _ in range(count):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"POST /v1/refine HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                  b"Content-Length: 268435456\r\n\r\nsolid")
        socks.append(s)
    with trickling(lambda: socks, 1.0):
        probe(port, seconds, f"{count} uploads declaring 256 MiB, 1 byte/s each")
    answered = 0
    for s in socks:
        s.settimeout(0.5)
        try:
            answered += s.recv(64).startswith(b"HTTP/1.1 408")
        except OSError:
            pass
        s.close()
    print(f"    {answered} of {count} slow uploads were answered 408", flush=True)


def trickling_heads(port, seconds, count=1100):
    socks = []
    for _ in range(count):
        try:
            s = socket.create_connection(("127.0.0.1", port))
            s.sendall(b"GET /v1/openapi.json HTTP/1.1\r\n")
            socks.append(s)
        except OSError:
            break
    with trickling(lambda: random.sample(socks, min(200, len(socks))), 0.5):
        probe(port, seconds, f"{len(socks)} sockets from one address trickling heads")
    for s in socks:
        s.close()


def non_readers(port, seconds, stl_path, count=6):
    with open(stl_path, "rb") as f:
        body = f.read()
    socks = []
    for _ in range(count):
        s = socket.create_connection(("127.0.0.1", port))
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.sendall(post("/v1/refine?levels=3", body))
        socks.append(s)
    probe(port, seconds, f"{count} clients never reading a 41 MB answer")
    for s in socks:
        s.close()


def random_methods(port, count=3000):
    before = len(request(port, b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")[1])
    for _ in range(count):
        m = "".join(random.choice("ABCDEFGHIJKLMNOPQRSTUVWXYZ") for _ in range(12))
        request(port, f"{m} /healthz HTTP/1.1\r\nHost: x\r\n\r\n".encode(), timeout=2)
    after = len(request(port, b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n")[1])
    print(f"[{count} random methods] /metrics {before} -> {after} bytes", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=20)
    ap.add_argument("--stl", default=os.path.join(os.path.dirname(__file__), "..", "..",
                                                  "examples", "fandisk.stl"))
    a = ap.parse_args()
    probe(a.port, 3, "idle")
    slow_uploads(a.port, a.seconds)
    trickling_heads(a.port, a.seconds)
    non_readers(a.port, a.seconds, a.stl)
    random_methods(a.port)


if __name__ == "__main__":
    main()
