#!/usr/bin/env python3
# Issue 19 round 5 figures (bench/results-issue19-s5-parts.md), against a running stlrefined:
#  parts   - a zip of N copies of a part as one job vs N single jobs (run seconds);
#  streams - /healthz latency with 0 and S idle event streams open on a running job.
# Standard library only. Usage:
#   bench/parts_streams.py URL parts PART.stl N QUERY
#   bench/parts_streams.py URL streams PART.stl S QUERY
import io, json, socket, statistics, sys, time, urllib.parse, urllib.request, zipfile


def post(url, body, ctype):
    req = urllib.request.Request(url, data=body, method="POST", headers={"Content-Type": ctype})
    with urllib.request.urlopen(req) as r:
        return r.headers["Location"], json.load(r)


def get(url):
    with urllib.request.urlopen(url) as r:
        return json.load(r)


def wait(base, loc):
    while True:
        job = get(base + loc)
        if job["state"] not in ("queued", "running"):
            return job
        time.sleep(0.05)


def parts(base, part, n, query):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for k in range(n):
            z.writestr(f"copy{k}.stl", part)
    loc, _ = post(f"{base}/v1/jobs?{query}", buf.getvalue(), "application/zip")
    job = wait(base, loc)
    assert job["state"] == "done", job
    single = []
    for _ in range(n):
        loc1, _ = post(f"{base}/v1/jobs?{query}", part, "model/stl")
        single.append(wait(base, loc1)["timings"]["run_seconds"])
    print(f"zip of {n}: run {job['timings']['run_seconds']:.2f} s, parts {len(job['parts'])}, "
          f"faces {job['report']['output']['faces']}; {n} single jobs: run "
          f"{sum(single):.2f} s ({', '.join(f'{s:.2f}' for s in single)})")


def healthz(host, port, count=200):
    lat = []
    for _ in range(count):
        t = time.perf_counter()
        with urllib.request.urlopen(f"http://{host}:{port}/healthz") as r:
            r.read()
        lat.append((time.perf_counter() - t) * 1000)
    lat.sort()
    return f"p50 {statistics.median(lat):.2f} ms, p99 {lat[int(0.99 * len(lat)) - 1]:.2f} ms, max {lat[-1]:.2f} ms"


def streams(base, part, s, query):
    u = urllib.parse.urlparse(base)
    print(f"0 streams: /healthz {healthz(u.hostname, u.port)}")
    loc, _ = post(f"{base}/v1/jobs?{query}", part, "model/stl")
    socks, refused = [], 0
    for _ in range(s):
        c = socket.create_connection((u.hostname, u.port))
        c.sendall(f"GET {loc}/events HTTP/1.1\r\nHost: x\r\n\r\n".encode())
        head = c.recv(4096)
        if b" 200 " not in head.split(b"\r\n")[0]:
            refused += 1
        socks.append(c)  # held open, never read again: an idle client
    print(f"{s} streams open ({refused} refused): /healthz {healthz(u.hostname, u.port)}; "
          f"job state {get(base + loc)['state']}")
    for c in socks:
        c.close()


if __name__ == "__main__":
    base, mode, path, n, query = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5]
    part = open(path, "rb").read()
    (parts if mode == "parts" else streams)(base, part, n, query)
