"""A Python client for moreau-server's job API (docs/api.md, server/openapi.json).

Standard library only (Python 3.9 or later); trajectories come back as numpy arrays when numpy is
installed, as lists otherwise.

    from moreau_client import Client
    c = Client("http://127.0.0.1:8080")             # or MOREAU_SERVER; token from MOREAU_TOKEN
    job = c.run("manipulator", overrides={"integrator.t_end": 2})
    print(job.report["convergence"])
    traj = c.trajectory(job.id)                     # {"t": array, "x1": array, ...}
    open("state.png", "wb").write(c.figure(job.id, kind="state"))

Every error the server answers is raised as MoreauError, carrying its HTTP status and the server's
`error`, `reason`, and the JSON `pointer` of the field it is about (and `where`: "scene" or "request").
"""

import json
import os
import socket
import time
import urllib.error
import urllib.parse
import urllib.request

__all__ = ["Client", "Job", "Event", "MoreauError"]

FINAL_STATES = ("done", "failed", "cancelled")


class MoreauError(Exception):
    """An error answer of the server: `status` (HTTP), `error` (short, stable), `reason` (what to change),
    `pointer` (a JSON pointer into the scene or the request, or None), `where` ("scene", "request" or None)."""

    def __init__(self, status, error, reason="", pointer=None, where=None):
        self.status = status
        self.error = error
        self.reason = reason
        self.pointer = pointer
        self.where = where
        text = "%d %s" % (status, error)
        if pointer is not None:
            text += " at %s%s" % (where + " " if where else "", pointer)
        if reason:
            text += ": " + reason
        super().__init__(text)


class Job:
    """A job, a study or a campaign as the server describes it. `raw` is the JSON object; the common fields
    are attributes: id, kind ("run", "study" or "campaign"), state, scene, progress, reason (or None), and
    report (a run's, once final), result (a study's, once done) or summary (a campaign's, once done)."""

    def __init__(self, raw):
        self.raw = raw
        self.id = raw["id"]
        self.kind = raw.get("kind", "run")
        self.state = raw["state"]
        self.scene = raw.get("scene")
        self.progress = raw.get("progress", {})
        self.reason = raw.get("reason")
        self.report = raw.get("report")
        self.result = raw.get("result")
        self.summary = raw.get("summary")

    @property
    def final(self):
        return self.state in FINAL_STATES

    def __repr__(self):
        return "Job(id=%r, kind=%r, state=%r, scene=%r)" % (self.id, self.kind, self.state, self.scene)


class Event:
    """One server-sent event: `id` (int), `name` ("state", "progress", ...) and `data` (decoded JSON)."""

    def __init__(self, id, name, data):
        self.id = id
        self.name = name
        self.data = data

    def __repr__(self):
        return "Event(id=%r, name=%r, data=%r)" % (self.id, self.name, self.data)


class Client:
    """A connection to one server. `url` defaults to MOREAU_SERVER, else http://127.0.0.1:8080; `token`
    to MOREAU_TOKEN. `timeout` bounds each request (seconds), not the whole wait for a job."""

    def __init__(self, url=None, token=None, timeout=60.0):
        self.url = (url or os.environ.get("MOREAU_SERVER") or "http://127.0.0.1:8080").rstrip("/")
        self.token = token if token is not None else os.environ.get("MOREAU_TOKEN")
        self.timeout = timeout

    # -- requests -------------------------------------------------------------------------------

    def _open(self, method, path, query=None, body=None, headers=None, timeout=None):
        url = self.url + path
        if query:
            url += "?" + urllib.parse.urlencode({k: v for k, v in query.items() if v is not None})
        data = None
        req_headers = {"Accept": "*/*"}
        if body is not None:
            data = json.dumps(body).encode("utf-8")
            req_headers["Content-Type"] = "application/json"
        if self.token:
            req_headers["Authorization"] = "Bearer " + self.token
        req_headers.update(headers or {})
        req = urllib.request.Request(url, data=data, method=method, headers=req_headers)
        try:
            return urllib.request.urlopen(req, timeout=timeout or self.timeout)
        except urllib.error.HTTPError as e:
            raise self._error(e.code, e.read()) from None
        except urllib.error.URLError as e:
            raise MoreauError(0, "cannot reach the server", "%s: %s" % (self.url, e.reason)) from None

    def _error(self, status, body):
        try:
            j = json.loads(body)
        except ValueError:
            j = None
        if not isinstance(j, dict) or "error" not in j:
            return MoreauError(status, "HTTP %d" % status, body.decode("utf-8", "replace")[:1000])
        reason = j.get("reason", "")
        if status == 401:
            reason += (" (pass the server's token as Client(token=...) or in MOREAU_TOKEN)" if not self.token
                       else " (the token given was not accepted)")
        return MoreauError(status, j["error"], reason, j.get("pointer"), j.get("where"))

    def _json(self, method, path, query=None, body=None, timeout=None):
        with self._open(method, path, query, body, timeout=timeout) as r:
            return json.loads(r.read())

    def _bytes(self, path, query=None):
        with self._open("GET", path, query) as r:
            return r.read()

    # -- the service ----------------------------------------------------------------------------

    def health(self):
        return self._json("GET", "/healthz")

    def openapi(self):
        """The server's OpenAPI 3.1 document."""
        return self._json("GET", "/v1/openapi.json")

    def scenes(self):
        """The shipped scenes: a list of {name, title, description, url}."""
        return self._json("GET", "/v1/scenes")["scenes"]

    def scene(self, name):
        """One shipped scene, as a dict (edit it and submit it)."""
        return self._json("GET", "/v1/scenes/" + urllib.parse.quote(name, safe=""))

    # -- jobs -----------------------------------------------------------------------------------

    def submit(self, scene, overrides=None, stream=None, strict=False):
        """Queues a run. `scene`: a scene dict, the name of a shipped scene, or a path (os.PathLike) to a
        scene file. `overrides`: {"integrator.t_end": 2, ...} or ["integrator.t_end=2", ...].
        `stream`: True, or {"channel": ..., "period": ..., "realtime": ...} to publish over LCM."""
        body = {"scene": _scene_value(scene)}
        if overrides is not None:
            body["overrides"] = overrides
        if stream is not None:
            body["stream"] = stream
        if strict:
            body["strict"] = True
        return Job(self._json("POST", "/v1/jobs", body=body))

    def job(self, job_id, wait=None):
        """The job; with `wait` (seconds, at most 60), held until it is final or that time has passed."""
        return Job(self._json("GET", "/v1/jobs/" + job_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def jobs(self, state=None, scene=None, limit=None):
        """The jobs (oldest first) matching `state` and `scene`; with `limit`, the most recent that many.
        Queued ones carry `raw["queue_position"]`."""
        return [Job(j) for j in self._json("GET", "/v1/jobs", {"state": state, "scene": scene, "limit": limit})["jobs"]]

    def iter_jobs(self, state=None, scene=None, page_size=100):
        """Every job matching the filters, newest first, fetched a page at a time (the list's cursor)."""
        path = "/v1/jobs?" + urllib.parse.urlencode({k: v for k, v in (("limit", page_size), ("state", state), ("scene", scene)) if v})
        while path:
            page = self._json("GET", path)
            for j in reversed(page["jobs"]):
                yield Job(j)
            path = page.get("next")

    def cancel(self, job_id):
        return Job(self._json("DELETE", "/v1/jobs/" + job_id))

    def purge(self, job_id):
        """Deletes a finished job with its results (MoreauError 409 if it is not final: cancel it first)."""
        return self._json("DELETE", "/v1/jobs/" + job_id, {"purge": "true"})

    def wait(self, job_id, timeout=None, progress=None):
        """Waits until the job (or study) is final and returns it. `progress(job)` is called each time its
        progress changes (from the server's event stream). Raises TimeoutError after `timeout` seconds."""
        return self._wait("/v1/jobs/", job_id, timeout, progress)

    def run(self, scene, overrides=None, timeout=None, progress=None, **submit_options):
        """submit() then wait(): the final job, with its report. Raises MoreauError if it failed."""
        return _unless_failed(self.wait(self.submit(scene, overrides, **submit_options).id, timeout, progress))

    def report(self, job_id):
        """The job's report (what `moreau run --json` prints)."""
        return self._json("GET", "/v1/jobs/%s/report" % job_id)

    def trajectory(self, job_id, start=None, stop=None, every=None, numpy=None):
        """The trajectory as columns {"t": ..., "h": ..., coordinate names..., "<name>_dot": ..., "energy": ...},
        numpy float arrays (NaN for a non-finite value) when numpy is installed (or numpy=True), lists
        (None for a non-finite value) otherwise. `start`/`stop` keep rows with start <= t <= stop, `every`
        every k-th of them."""
        j = self._json("GET", "/v1/jobs/%s/trajectory" % job_id, {"from": start, "to": stop, "every": every})
        columns = {name: j["data"][name] for name in j["columns"]}
        np = _numpy() if numpy is None or numpy else None
        if numpy and np is None:
            raise ImportError("numpy is not installed")
        if np is not None:
            return {k: np.array([np.nan if x is None else x for x in v], dtype=float) for k, v in columns.items()}
        return columns

    def trajectory_csv(self, job_id, start=None, stop=None, every=None):
        """The trajectory as the CSV text `moreau run --out` writes."""
        return self._bytes("/v1/jobs/%s/trajectory" % job_id,
                           {"format": "csv", "from": start, "to": stop, "every": every}).decode("utf-8")

    def figure(self, job_id, kind="state", format="png", width=None, height=None, path=None):
        """A figure of the job (kind: state, energy, step, phase, tracking) as PNG or SVG bytes; with `path`, also
        written to that file."""
        return self._figure("/v1/jobs/%s/figure" % job_id, kind, format, width, height, path)

    def events(self, job_id, last_event_id=None):
        """The job's server-sent events, as Event objects, until the stream ends (after the final state).
        `last_event_id` resumes after that event."""
        return self._events("/v1/jobs/%s/events" % job_id, last_event_id)

    # -- studies --------------------------------------------------------------------------------

    def submit_study(self, scene, overrides=None, **study):
        """Queues a study (docs/studies.md): study options h, schemes, reference_h, epsilon,
        regularization, eval_points, repeats as keyword arguments."""
        body = {"scene": _scene_value(scene)}
        if overrides is not None:
            body["overrides"] = overrides
        if study:
            body["study"] = study
        return Job(self._json("POST", "/v1/studies", body=body))

    def study(self, study_id, wait=None):
        return Job(self._json("GET", "/v1/studies/" + study_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def wait_study(self, study_id, timeout=None, progress=None):
        return self._wait("/v1/studies/", study_id, timeout, progress)

    def run_study(self, scene, overrides=None, timeout=None, progress=None, **study):
        """submit_study() then wait: the finished study, whose `result` holds the table and the fitted orders."""
        return _unless_failed(self.wait_study(self.submit_study(scene, overrides, **study).id, timeout, progress))

    def study_table_csv(self, study_id):
        return self._bytes("/v1/studies/%s/table" % study_id, {"format": "csv"}).decode("utf-8")

    def study_figure(self, study_id, kind="work", format="png", width=None, height=None, path=None):
        """A figure of the study (kind: work, order) as PNG or SVG bytes; with `path`, also written there."""
        return self._figure("/v1/studies/%s/figure" % study_id, kind, format, width, height, path)

    def cancel_study(self, study_id):
        return Job(self._json("DELETE", "/v1/studies/" + study_id))

    def study_events(self, study_id, last_event_id=None):
        return self._events("/v1/studies/%s/events" % study_id, last_event_id)

    # -- campaigns ------------------------------------------------------------------------------

    def submit_campaign(self, scene, campaign, overrides=None):
        """Queues a robustness campaign (docs/campaigns.md): `campaign` is a spec without its scene
        ({"inputs": [...], "sampler": ..., "samples": ..., "seed": ..., "target": ..., ...}); `scene` a
        shipped scene's name, a scene dict or a path to a scene file."""
        body = {"scene": _scene_value(scene), "campaign": campaign}
        if overrides is not None:
            body["overrides"] = overrides
        return Job(self._json("POST", "/v1/campaigns", body=body))

    def campaign(self, campaign_id, wait=None):
        """The campaign; its `summary` (success rate and interval, quantiles, worst samples, rank
        correlations) once done, and `progress` {samples, samples_total, fraction}."""
        return Job(self._json("GET", "/v1/campaigns/" + campaign_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def wait_campaign(self, campaign_id, timeout=None, progress=None):
        return self._wait("/v1/campaigns/", campaign_id, timeout, progress)

    def run_campaign(self, scene, campaign, overrides=None, timeout=None, progress=None):
        """submit_campaign() then wait: the finished campaign, with its `summary`."""
        return _unless_failed(self.wait_campaign(self.submit_campaign(scene, campaign, overrides).id, timeout, progress))

    def campaign_samples(self, campaign_id):
        """The records of the samples that finished (also of a cancelled campaign), one dict per sample, in
        the order they finished."""
        text = self._bytes("/v1/campaigns/%s/samples" % campaign_id, {"format": "jsonl"}).decode("utf-8")
        return [json.loads(line) for line in text.splitlines() if line]

    def campaign_samples_csv(self, campaign_id):
        return self._bytes("/v1/campaigns/%s/samples" % campaign_id, {"format": "csv"}).decode("utf-8")

    def campaign_figure(self, campaign_id, kind="convergence-cdf", format="png", width=None, height=None, path=None):
        """A figure of the campaign (kind: convergence-cdf, inputs, success-map) as PNG or SVG bytes."""
        return self._figure("/v1/campaigns/%s/figure" % campaign_id, kind, format, width, height, path)

    def cancel_campaign(self, campaign_id):
        return Job(self._json("DELETE", "/v1/campaigns/" + campaign_id))

    def campaign_events(self, campaign_id, last_event_id=None):
        return self._events("/v1/campaigns/%s/events" % campaign_id, last_event_id)

    # -- helpers --------------------------------------------------------------------------------

    def _figure(self, path, kind, format, width, height, file):
        data = self._bytes(path, {"kind": kind, "format": format, "width": width, "height": height})
        if file is not None:
            with open(file, "wb") as f:
                f.write(data)
        return data

    def _wait(self, prefix, job_id, timeout, progress):
        deadline = None if timeout is None else time.monotonic() + timeout
        last = None
        while True:
            left = 60.0 if deadline is None else min(60.0, deadline - time.monotonic())
            if left <= 0:
                raise TimeoutError("%s%s is not final after %s s" % (prefix, job_id, timeout))
            if progress is None:
                job = Job(self._json("GET", prefix + job_id, {"wait": round(left, 3)}, timeout=left + self.timeout))
                if job.final:
                    return job
                continue
            # With a progress callback: follow the event stream, which ends after the final state. Reads
            # wait at most until the deadline (the server's keep-alive comes only every 15 s).
            try:
                for event in self._events(prefix + job_id + "/events", last, timeout=left if deadline is not None else None):
                    last = event.id
                    if event.name in ("progress", "state"):
                        progress(Job(self._json("GET", prefix + job_id)))
                    if deadline is not None and time.monotonic() > deadline:
                        break
            except (socket.timeout, TimeoutError):
                if deadline is None or time.monotonic() < deadline:
                    raise
            job = Job(self._json("GET", prefix + job_id))
            if job.final:
                return job

    def _events(self, path, last_event_id, timeout=None):
        headers = {"Accept": "text/event-stream"}
        if last_event_id is not None:
            headers["Last-Event-ID"] = str(last_event_id)
        try:
            r = self._open("GET", path, headers=headers, timeout=timeout or max(self.timeout, 30.0))
        except MoreauError as e:
            if e.status == 0 and "timed out" in e.reason:
                raise socket.timeout(e.reason) from None
            raise
        with r:
            event_id, name, data = None, "message", []
            for raw in r:
                line = raw.decode("utf-8").rstrip("\r\n")
                if line == "":
                    if data:
                        yield Event(event_id, name, json.loads("\n".join(data)))
                    event_id, name, data = None, "message", []
                elif line.startswith(":"):
                    continue  # a comment: the keep-alive
                else:
                    field, _, value = line.partition(":")
                    value = value[1:] if value.startswith(" ") else value
                    if field == "id":
                        event_id = int(value)
                    elif field == "event":
                        name = value
                    elif field == "data":
                        data.append(value)


def _unless_failed(job):
    if job.state == "failed":
        raise MoreauError(200, ("study" if job.kind == "study" else "job") + " failed", job.reason or "")
    return job


def _scene_value(scene):
    if isinstance(scene, (dict, str)):
        return scene
    if isinstance(scene, os.PathLike):
        with open(scene, encoding="utf-8") as f:
            return json.load(f)
    raise TypeError("scene must be a dict, the name of a shipped scene, or a path (os.PathLike) to a scene file")


def _numpy():
    try:
        import numpy
    except ImportError:
        return None
    return numpy
