#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
# Copyright (c) 2026 stlrefine authors
"""A small stlrefine client (Python 3 standard library only).

Submits an STL to /v1/jobs, polls the job until its `state` says it ended (`state` is the
only word that says done), and downloads every result next to the input:

    python3 examples/stlrefine_client.py part.stl --url http://localhost:8080 \
        --param scheme=lsf --param levels=2 --param layer_height=0.2 --param slice_format=svg

With an API key: --api-key KEY (or STLREFINE_API_KEY). Exit 0 when the job is done, 1 when
it failed or was cancelled (its problem is printed), 2 on a usage or transport error.
"""

import argparse
import json
import os
import sys
import time
import urllib.error
import urllib.parse
import urllib.request


class ClientError(Exception):
    pass


def request(method, url, api_key=None, body=None, content_type=None):
    headers = {"Accept": "application/json"}
    if api_key:
        headers["Authorization"] = "Bearer " + api_key
    if content_type:
        headers["Content-Type"] = content_type
    req = urllib.request.Request(url, data=body, method=method, headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=120) as res:
            return res.status, dict(res.headers), res.read()
    except urllib.error.HTTPError as e:
        return e.code, dict(e.headers), e.read()
    except urllib.error.URLError as e:
        raise ClientError(f"{method} {url}: {e.reason}") from e


def problem_text(status, body):
    try:
        p = json.loads(body)
        field = f" (field {p['field']})" if p.get("field") else ""
        return f"{status} {p.get('title', '')}: {p.get('detail', '')}{field}"
    except (ValueError, AttributeError):
        return f"{status}: {body[:200]!r}"


def submit(base, path, params, api_key):
    with open(path, "rb") as f:
        data = f.read()
    url = base + "/v1/jobs?" + urllib.parse.urlencode(params)
    for _ in range(30):  # 503 busy: wait as told
        status, headers, body = request("POST", url, api_key, data, "model/stl")
        if status == 503 and "Retry-After" in headers:
            time.sleep(min(float(headers["Retry-After"]), 10))
            continue
        break
    if status != 202:
        raise ClientError("submit: " + problem_text(status, body))
    return json.loads(body)


def wait(base, job, api_key, poll_seconds, timeout):
    deadline = time.monotonic() + timeout
    url = base + job["links"]["self"]
    while True:
        status, _, body = request("GET", url, api_key)
        if status != 200:
            raise ClientError("poll: " + problem_text(status, body))
        job = json.loads(body)
        print(f"{job['state']:9} {100 * job.get('progress', 0):5.1f}% {job.get('stage', '')}",
              file=sys.stderr)
        if job["state"] in ("done", "failed", "cancelled"):
            return job
        if time.monotonic() > deadline:
            raise ClientError(f"job {job['id']} did not end within {timeout} s")
        time.sleep(poll_seconds)


def download(base, job, api_key, out_dir, stem):
    saved = []
    for key, link in job["links"].items():
        if key == "self":
            continue
        status, _, body = request("GET", base + link, api_key)
        if status != 200:
            raise ClientError(f"download {link}: " + problem_text(status, body))
        name = link.rsplit("/", 1)[-1]  # result.stl, report.json, contours.svg, ...
        target = os.path.join(out_dir, f"{stem}_{name}")
        with open(target, "wb") as f:
            f.write(body)
        saved.append(target)
    return saved


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stl", help="the STL file to refine")
    ap.add_argument("--url", default=os.environ.get("STLREFINE_URL", "http://localhost:8080"))
    ap.add_argument("--api-key", default=os.environ.get("STLREFINE_API_KEY"))
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                    help="a request parameter (repeatable): scheme=lsf, levels=2, units=m, ...")
    ap.add_argument("--out-dir", default=None, help="where results go (default: beside the STL)")
    ap.add_argument("--poll", type=float, default=0.5, help="seconds between polls")
    ap.add_argument("--timeout", type=float, default=3600, help="give up after this many seconds")
    args = ap.parse_args(argv)

    params = []
    for p in args.param:
        if "=" not in p:
            ap.error(f"--param {p!r} is not NAME=VALUE")
        params.append(tuple(p.split("=", 1)))
    base = args.url.rstrip("/")
    stem = os.path.splitext(os.path.basename(args.stl))[0]
    out_dir = args.out_dir or os.path.dirname(os.path.abspath(args.stl))
    try:
        job = submit(base, args.stl, params, args.api_key)
        print(f"submitted {job['id']}", file=sys.stderr)
        job = wait(base, job, args.api_key, args.poll, args.timeout)
        if job["state"] != "done":
            problem = job.get("problem", {})
            print(f"job {job['id']} {job['state']}: {problem.get('detail', '')}", file=sys.stderr)
            return 1
        for path in download(base, job, args.api_key, out_dir, stem):
            print(path)
        return 0
    except (ClientError, OSError) as e:
        print(f"stlrefine_client: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
