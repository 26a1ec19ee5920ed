#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
# Copyright (c) 2026 stlrefine authors
"""A small stlrefine client (Python 3 standard library only).

Uploads an STL to /v1/jobs as a form (the server keeps its name), follows the job by its
server-sent events (GET /v1/jobs/{id}/events; polling when they cannot be had, or with
--no-events) until its `state` says it ended (`state` is the only word that says done), and
downloads every result next to the input under the name the server gives it
(Content-Disposition: part_refined.stl, part_slices.svg, part_report.json):

    python3 examples/stlrefine_client.py part.stl --url http://localhost:8080 \
        --param scheme=lsf --param levels=2 --param layer_height=0.2 --param slice_format=svg

With an API key: --api-key KEY (or STLREFINE_API_KEY). Exit 0 when the job is done, 1 when
it failed or was cancelled (its problem is printed), 2 on a usage or transport error.
"""

import argparse
import json
import os
import re
import sys
import time
import uuid
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


def form_body(path):
    """multipart/form-data with the file as its one part named `file`."""
    with open(path, "rb") as f:
        data = f.read()
    boundary = "stlrefine-" + uuid.uuid4().hex
    name = os.path.basename(path).replace("\\", "_").replace('"', "_")
    head = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; "
            f"filename=\"{name}\"\r\nContent-Type: application/octet-stream\r\n\r\n")
    body = head.encode("utf-8") + data + f"\r\n--{boundary}--\r\n".encode("ascii")
    return body, "multipart/form-data; boundary=" + boundary


def submit(base, path, params, api_key):
    data, content_type = form_body(path)
    url = base + "/v1/jobs?" + urllib.parse.urlencode(params)
    for _ in range(30):  # 503 busy: wait as told
        status, headers, body = request("POST", url, api_key, data, content_type)
        if status == 503 and "Retry-After" in headers:
            time.sleep(min(float(headers["Retry-After"]), 10))
            continue
        break
    if status != 202:
        raise ClientError("submit: " + problem_text(status, body))
    return json.loads(body)


def show(job):
    print(f"{job['state']:9} {100 * job.get('progress', 0):5.1f}% {job.get('stage', '')}",
          file=sys.stderr)


def follow(base, job, api_key, timeout):
    """The job's server-sent events until its `end` event; None when the stream cannot be
    had or breaks off (the caller polls then)."""
    headers = {"Accept": "text/event-stream"}
    if api_key:
        headers["Authorization"] = "Bearer " + api_key
    req = urllib.request.Request(base + job["links"]["self"] + "/events", headers=headers)
    try:
        with urllib.request.urlopen(req, timeout=min(timeout, 60)) as res:
            if not res.headers.get("Content-Type", "").startswith("text/event-stream"):
                return None
            event, data = None, []
            for raw in res:
                line = raw.decode("utf-8", "replace").rstrip("\r\n")
                if line.startswith(":"):
                    continue  # keep-alive
                if line.startswith("event:"):
                    event = line[6:].strip()
                elif line.startswith("data:"):
                    data.append(line[5:].strip())
                elif not line and data:
                    j = json.loads("\n".join(data))
                    if event in ("progress", "end"):
                        show(j)
                    if event == "end":
                        return j
                    event, data = None, []
    except (urllib.error.URLError, OSError, ValueError):
        pass
    return None


def wait(base, job, api_key, poll_seconds, timeout):
    deadline = time.monotonic() + timeout
    url = base + job["links"]["self"]
    while True:
        status, _, body = request("GET", url, api_key)
        if status != 200:
            raise ClientError("poll: " + problem_text(status, body))
        job = json.loads(body)
        show(job)
        if job["state"] in ("done", "failed", "cancelled"):
            return job
        if time.monotonic() > deadline:
            raise ClientError(f"job {job['id']} did not end within {timeout} s")
        time.sleep(poll_seconds)


def served_name(disposition):
    """The file name of a Content-Disposition (RFC 6266: filename* first), as a plain
    name: no directory part can come from the server."""
    m = re.search(r"filename\*=UTF-8''([^;]+)", disposition or "", re.I)
    if m:
        name = urllib.parse.unquote(m.group(1).strip())
    else:
        m = re.search(r'filename="([^"]*)"', disposition or "")
        name = m.group(1) if m else ""
    name = os.path.basename(name.replace("\\", "/"))
    return name if name not in ("", ".", "..") else None


def download(base, job, api_key, out_dir, stem):
    saved = []
    for key, link in job["links"].items():
        if key == "self":
            continue
        status, headers, body = request("GET", base + link, api_key)
        if status != 200:
            raise ClientError(f"download {link}: " + problem_text(status, body))
        # part_refined.stl, part_slices.svg, ...; else result.stl -> part_result.stl
        name = served_name(headers.get("Content-Disposition"))
        name = name or f"{stem}_{link.rsplit('/', 1)[-1]}"
        target = os.path.join(out_dir, name)
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
    ap.add_argument("--no-events", action="store_true",
                    help="poll the job instead of following its server-sent events")
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
        followed = None if args.no_events else follow(base, job, args.api_key, args.timeout)
        if followed is None and not args.no_events:
            print("no event stream: polling", file=sys.stderr)
        job = followed or wait(base, job, args.api_key, args.poll, args.timeout)
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
