"""A Python client for moreau-server's job API (docs/api.md, server/openapi.json, docs/python-client.md).

Standard library and numpy only (Python 3.9 or later); without numpy it still works, trajectories then
coming back as lists. It needs nothing compiled: `from moreau.client import Client` works where the
package's compiled part (moreau._moreau) is not built.

    from pathlib import Path
    from moreau.client import Client
    c = Client("http://127.0.0.1:8080")             # or MOREAU_SERVER; token from MOREAU_TOKEN
    r = c.run("manipulator", set={"integrator.t_end": 2})            # a shipped scene, by name
    r = c.run(Path("my-scene.json"), integrator={"h": 1e-4})         # a scene file, with a patch
    print(r.report["converged_time"], r.q[-1])      # a moreau.result.Result, as moreau.run gives
    open("state.png", "wb").write(r.figure("state"))

The scene argument says what it is by its type: a `dict` is a scene, a `pathlib.Path` (any os.PathLike)
a scene file read here, a `str` the name of one of the server's shipped scenes. A `str` that looks like a
path (it ends with .json or has a '/') is refused with a ValueError naming Path(...): a scene file is
never sent by its name.

Errors (moreau.errors): an error answer of the server is a ServerError with its HTTP status, `error`,
`reason`, the JSON `pointer` of the field it is about and `where` ("scene" or "request"); one about the
scene is also a SceneError. No answer at all (refused, reset, unknown host, timed out) is
ServerUnreachable, a ConnectionError. A run that failed raises RunFailed, one that failed a hypothesis
with strict=True HypothesisFailed, each carrying what was computed as `result`.
"""

from __future__ import annotations

import heapq
import http.client
import json
import os
import re
import socket
import time
import urllib.error
import urllib.parse
import urllib.request
from typing import TYPE_CHECKING, Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

from .overrides import set_list
from .errors import (HypothesisFailed, MoreauError, RunFailed, SceneError, ServerError, ServerSceneError,
                     ServerUnreachable)

if TYPE_CHECKING:  # numpy and moreau.result (which needs numpy) are imported when first used
    import numpy as np

    from .result import Result

__all__ = ["Client", "Job", "Event", "MoreauError", "ServerError", "ServerSceneError", "ServerUnreachable",
           "SceneError", "RunFailed", "HypothesisFailed", "FINAL_STATES"]

FINAL_STATES = ("done", "failed", "cancelled")
KINDS = ("run", "study", "campaign")
_PREFIX = {"run": "/v1/jobs", "study": "/v1/studies", "campaign": "/v1/campaigns"}
_LIST_KEY = {"run": "jobs", "study": "studies", "campaign": "campaigns"}

# A scene: a dict, a file (os.PathLike) or a shipped scene's name.
SceneArg = Union[Mapping[str, Any], "os.PathLike[str]", str]
# Overrides: {"integrator.h": 1e-4} (a dotted path or a JSON pointer, to a JSON value) or ["integrator.h=1e-4"].
Overrides = Union[Mapping[str, Any], Sequence[str]]
Progress = Callable[["Job"], None]


class Job:
    """A run, a study or a campaign as the server describes it. `raw` is the JSON object; the common fields
    are attributes: id, kind ("run", "study" or "campaign"), state, scene, progress, reason (or None), and
    report (a run's, once final), result (a study's, once done) or summary (a campaign's, once done)."""

    def __init__(self, raw: Dict[str, Any]) -> None:
        self.raw = raw
        self.id: str = raw["id"]
        self.kind: str = raw.get("kind", "run")
        self.state: str = raw["state"]
        self.scene: Optional[str] = raw.get("scene")
        self.progress: Dict[str, Any] = raw.get("progress", {})
        self.reason: Optional[str] = raw.get("reason")
        self.report: Optional[Dict[str, Any]] = raw.get("report")
        self.result: Optional[Dict[str, Any]] = raw.get("result")
        self.summary: Optional[Dict[str, Any]] = raw.get("summary")

    @property
    def final(self) -> bool:
        return self.state in FINAL_STATES

    @property
    def strict_failure(self) -> bool:
        """Whether the job failed because strict was set and a hypothesis it relies on fails (the command
        line's exit code 3), not because the run itself failed: the server says so by the reason's first
        word, "strict: <theorem>: <hypothesis> fails ..."."""
        return self.state == "failed" and (self.reason or "").startswith("strict: ")

    def __repr__(self) -> str:
        return "Job(id=%r, kind=%r, state=%r, scene=%r)" % (self.id, self.kind, self.state, self.scene)


class Event:
    """One server-sent event: `id` (int), `name` ("state", "progress", ...) and `data` (decoded JSON)."""

    def __init__(self, id: Optional[int], name: str, data: Any) -> None:
        self.id = id
        self.name = name
        self.data = data

    def __repr__(self) -> str:
        return "Event(id=%r, name=%r, data=%r)" % (self.id, self.name, self.data)


class Client:
    """A connection to one server. `url` defaults to MOREAU_SERVER, else http://127.0.0.1:8080; `token`
    to MOREAU_TOKEN. `timeout` bounds each request (seconds), not the whole wait for a job."""

    def __init__(self, url: Optional[str] = None, token: Optional[str] = None, timeout: float = 60.0) -> None:
        self.url: str = (url or os.environ.get("MOREAU_SERVER") or "http://127.0.0.1:8080").rstrip("/")
        self.token: Optional[str] = token if token is not None else os.environ.get("MOREAU_TOKEN")
        self.timeout = timeout

    def __repr__(self) -> str:
        return "Client(%r)" % self.url

    # -- requests -------------------------------------------------------------------------------

    def _open(self, method: str, path: str, query: Optional[Mapping[str, Any]] = None, body: Any = None,
              headers: Optional[Mapping[str, str]] = None, timeout: Optional[float] = None,
              raw_timeouts: bool = False) -> http.client.HTTPResponse:
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
            try:
                body = e.read()
            except (OSError, http.client.HTTPException):
                body = b""
            raise self._error(e.code, body) from None
        except urllib.error.URLError as e:
            if raw_timeouts and isinstance(e.reason, socket.timeout):
                raise socket.timeout(str(e.reason)) from None
            raise ServerUnreachable(self.url, str(e.reason)) from None
        except socket.timeout as e:
            if raw_timeouts:
                raise
            raise ServerUnreachable(self.url, "timed out (%s)" % e) from None
        except (OSError, http.client.HTTPException) as e:  # reset, closed without an answer
            raise ServerUnreachable(self.url, "%s: %s" % (type(e).__name__, e)) from None

    def _error(self, status: int, body: bytes) -> ServerError:
        try:
            j = json.loads(body)
        except ValueError:
            j = None
        if not isinstance(j, dict) or "error" not in j:
            return ServerError(status, "HTTP %d" % status, body.decode("utf-8", "replace")[:1000])
        reason = j.get("reason", "")
        if status == 401:
            reason += (" (pass the server's token as Client(token=...) or in MOREAU_TOKEN)" if not self.token
                       else " (the token given was not accepted)")
        cls = ServerSceneError if j.get("where") == "scene" and j.get("pointer") is not None else ServerError
        return cls(status, j["error"], reason, j.get("pointer"), j.get("where"))

    def _read(self, r: http.client.HTTPResponse) -> bytes:
        try:
            return r.read()
        except (OSError, http.client.HTTPException) as e:  # reset or timed out mid-answer
            raise ServerUnreachable(self.url, "the answer broke off: %s: %s" % (type(e).__name__, e)) from None

    def _json(self, method: str, path: str, query: Optional[Mapping[str, Any]] = None, body: Any = None,
              timeout: Optional[float] = None) -> Any:
        with self._open(method, path, query, body, timeout=timeout) as r:
            return json.loads(self._read(r))

    def _bytes(self, path: str, query: Optional[Mapping[str, Any]] = None) -> bytes:
        with self._open("GET", path, query) as r:
            return self._read(r)

    # -- the service ----------------------------------------------------------------------------

    def health(self) -> Dict[str, Any]:
        return self._json("GET", "/healthz")

    def openapi(self) -> Dict[str, Any]:
        """The server's OpenAPI 3.1 document."""
        return self._json("GET", "/v1/openapi.json")

    def scenes(self) -> List[Dict[str, Any]]:
        """The shipped scenes: a list of {name, title, description, url}."""
        return self._json("GET", "/v1/scenes")["scenes"]

    def scene(self, name: str) -> Dict[str, Any]:
        """One shipped scene, as a dict (edit it and submit it)."""
        return self._json("GET", "/v1/scenes/" + urllib.parse.quote(name, safe=""))

    # -- runs -----------------------------------------------------------------------------------

    def submit(self, scene: SceneArg, overrides: Optional[Overrides] = None, *, set: Optional[Mapping[str, Any]] = None,
               strict: bool = False, stream: Union[bool, Mapping[str, Any], None] = None, **patch: Any) -> Job:
        """Queues a run and returns it as the server accepted it.

        `scene`: a dict, a pathlib.Path to a scene file, or a shipped scene's name (see the module's text).
        `set`: {"integrator.h": 1e-4, "initial.q": [1, 0]}: each dotted path (or JSON pointer) set to a
        JSON value, as `moreau run --set` does. Keyword arguments are a patch of the scene's top-level
        members, merged as a JSON merge patch: integrator={"h": 1e-4} changes h alone. The patch is
        applied first, then `set`. `overrides` is the older form of `set` ({path: value} or
        ["PATH=VALUE", ...]), applied last. `strict`: a hypothesis the run relies on that fails fails the
        run (the command line's --strict). `stream`: True, or {"channel": ..., "period": ...,
        "realtime": ...} to publish over LCM."""
        body: Dict[str, Any] = {"scene": _scene_value(scene)}
        assignments = _assignments(patch, set, overrides)
        if assignments:
            body["overrides"] = assignments
        if stream is not None:
            body["stream"] = stream
        if strict:
            body["strict"] = True
        return Job(self._json("POST", "/v1/jobs", body=body))

    def job(self, job_id: str, wait: Optional[float] = None) -> Job:
        """The run; with `wait` (seconds, at most 60), held until it is final or that time has passed."""
        return Job(self._json("GET", "/v1/jobs/" + job_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def jobs(self, state: Optional[str] = None, scene: Optional[str] = None, limit: Optional[int] = None,
             kind: Optional[str] = None) -> List[Job]:
        """Runs, studies and campaigns (oldest first) matching `state` and `scene`; `kind` ("run", "study"
        or "campaign") keeps one kind. With `limit`, the most recent that many. Queued ones carry
        `raw["queue_position"]`."""
        kinds = _kinds(kind)
        found: List[Job] = []
        for k in kinds:
            page = self._json("GET", _PREFIX[k], {"state": state, "scene": scene, "limit": limit})
            found += [Job(j) for j in page[_LIST_KEY[k]]]
        if len(kinds) > 1:
            found.sort(key=_created)
            if limit is not None:
                found = found[len(found) - min(limit, len(found)):]
        return found

    def iter_jobs(self, state: Optional[str] = None, scene: Optional[str] = None, page_size: int = 100,
                  kind: Optional[str] = None) -> Iterator[Job]:
        """Every run, study and campaign (or those of one `kind`) matching the filters, newest first,
        fetched a page at a time (each list's cursor)."""
        streams = [self._iter_kind(k, state, scene, page_size) for k in _kinds(kind)]
        if len(streams) == 1:
            return streams[0]
        return heapq.merge(*streams, key=_created, reverse=True)

    def _iter_kind(self, kind: str, state: Optional[str], scene: Optional[str], page_size: int) -> Iterator[Job]:
        query = {k: v for k, v in (("limit", page_size), ("state", state), ("scene", scene)) if v}
        path: Optional[str] = _PREFIX[kind] + "?" + urllib.parse.urlencode(query)
        while path:
            page = self._json("GET", path)
            for j in reversed(page[_LIST_KEY[kind]]):
                yield Job(j)
            path = page.get("next")

    def cancel(self, job_id: str) -> Job:
        return Job(self._json("DELETE", "/v1/jobs/" + job_id))

    def purge(self, job_id: str) -> Dict[str, Any]:
        """Deletes a finished run with its results (ServerError 409 if it is not final: cancel it first)."""
        return self._json("DELETE", "/v1/jobs/" + job_id, {"purge": "true"})

    def wait(self, job_id: str, timeout: Optional[float] = None, progress: Optional[Progress] = None) -> Job:
        """Waits until the run is final and returns it. `progress(job)` is called each time its progress
        changes (from the server's event stream). Raises TimeoutError after `timeout` seconds."""
        return self._wait("/v1/jobs/", job_id, timeout, progress)

    def run_job(self, scene: SceneArg, overrides: Optional[Overrides] = None, *, set: Optional[Mapping[str, Any]] = None,
                strict: bool = False, stream: Union[bool, Mapping[str, Any], None] = None, timeout: Optional[float] = None,
                progress: Optional[Progress] = None, **patch: Any) -> Job:
        """submit() then wait(): the final run as a Job, with its report (the trajectory is not fetched).
        Raises HypothesisFailed (strict) or RunFailed, with the Job as `result`, if it failed; a cancelled
        run is returned."""
        job = self.submit(scene, overrides, set=set, strict=strict, stream=stream, **patch)
        return _unless_failed(self.wait(job.id, timeout, progress))

    def run(self, scene: SceneArg, overrides: Optional[Overrides] = None, *, set: Optional[Mapping[str, Any]] = None,
            strict: bool = False, stream: Union[bool, Mapping[str, Any], None] = None, timeout: Optional[float] = None,
            progress: Optional[Progress] = None, **patch: Any) -> "Result":
        """Runs a scene on the server and returns its moreau.result.Result, as moreau.run does in process:
        the report, the trajectory (fetched as .npy) and the figures (drawn by the server). The arguments
        are submit()'s; `timeout` bounds the wait, `progress(job)` follows it. The Job is `result.job`.

        Raises RunFailed if the run failed or was cancelled, HypothesisFailed if strict and a hypothesis
        fails; each carries the Result (the trajectory up to where it stopped) as `result`."""
        job = self.submit(scene, overrides, set=set, strict=strict, stream=stream, **patch)
        job = self.wait(job.id, timeout, progress)
        if job.state == "done":
            return self.result(job)
        try:
            partial: Optional[Result] = self.result(job)
        except ServerError:  # no trajectory to show (a run refused at its start)
            partial = None
        if job.strict_failure:
            raise HypothesisFailed(job.reason or "a hypothesis fails", partial)
        raise RunFailed("the run %s %s: %s" % (job.id, job.state, job.reason or ""), partial)

    def result(self, job: Union[str, Job]) -> "Result":
        """A finished run (by id, or its Job) as a moreau.result.Result: the report, the trajectory as one
        float64 table (the .npy download) and figures through the server's figure endpoint. The Job is
        `result.job`. Needs numpy."""
        from .result import Result

        if isinstance(job, str):
            job = self.job(job)
        report = job.report if job.report is not None else self.report(job.id)
        table, columns = self.trajectory_array(job.id)
        n, signals = _split_columns(columns)
        job_id = job.id

        def figure_source(kind: str, format: str, width: Optional[int], height: Optional[int]) -> bytes:
            return self.figure(job_id, kind=kind, format=format, width=width, height=height)

        result = Result(table, columns[2:2 + n], columns[2 + n:2 + 2 * n], signals, report, None, figure_source)
        result.job = job
        return result

    def report(self, job_id: str) -> Dict[str, Any]:
        """The run's report (what `moreau run --json` prints)."""
        return self._json("GET", "/v1/jobs/%s/report" % job_id)

    def trajectory(self, job_id: str, start: Optional[float] = None, stop: Optional[float] = None,
                   every: Optional[int] = None, numpy: Optional[bool] = None,
                   format: Optional[str] = None) -> Dict[str, Any]:
        """The trajectory as columns {"t": ..., "h": ..., positions..., velocities..., "energy": ...,
        signals...}. With numpy (installed, or numpy=True): float64 arrays, views of one table downloaded
        as .npy (format="npy", the default then; NaN for a non-finite value). Without numpy (or
        numpy=False): lists from the JSON form (None for a non-finite value). format="json" with numpy
        asks for the JSON form and converts it. `start`/`stop` keep rows with start <= t <= stop, `every`
        every k-th of them."""
        np_ = _numpy() if numpy is None or numpy else None
        if numpy and np_ is None:
            raise ImportError("numpy is not installed (Debian: python3-numpy)")
        if format is None:
            format = "npy" if np_ is not None else "json"
        if format not in ("npy", "json"):
            raise ValueError("format must be npy or json (trajectory_csv() gives the CSV)")
        if format == "npy":
            if np_ is None:
                raise ImportError("format='npy' needs numpy (Debian: python3-numpy; numpy=False asks for lists)")
            table, columns = self.trajectory_array(job_id, start, stop, every)
            return {name: table[:, i] for i, name in enumerate(columns)}
        j = self._json("GET", "/v1/jobs/%s/trajectory" % job_id, {"from": start, "to": stop, "every": every})
        lists = {name: j["data"][name] for name in j["columns"]}
        if np_ is not None:
            return {k: np_.array([np_.nan if x is None else x for x in v], dtype=np_.float64) for k, v in lists.items()}
        return lists

    def trajectory_array(self, job_id: str, start: Optional[float] = None, stop: Optional[float] = None,
                         every: Optional[int] = None) -> Tuple["np.ndarray", List[str]]:
        """The trajectory as one (rows, columns) float64 array and its column names, downloaded as .npy
        and read straight into the array (no per-value Python objects). Needs numpy."""
        np_ = _numpy()
        if np_ is None:
            raise ImportError("trajectory_array() needs numpy (Debian: python3-numpy)")
        query = {"format": "npy", "from": start, "to": stop, "every": every}
        with self._open("GET", "/v1/jobs/%s/trajectory" % job_id, query) as r:
            header = r.getheader("Moreau-Columns")
            if header is None:
                raise ServerError(r.status, "no Moreau-Columns header", "the server does not serve trajectories as .npy")
            columns = [urllib.parse.unquote(name) for name in header.split(",")]
            try:
                table = _read_npy(np_, r)
            except (OSError, http.client.HTTPException) as e:
                raise ServerUnreachable(self.url, "the answer broke off: %s: %s" % (type(e).__name__, e)) from None
        if table.shape[1] != len(columns):
            raise ValueError("the .npy has %d columns, Moreau-Columns names %d" % (table.shape[1], len(columns)))
        return table, columns

    def trajectory_csv(self, job_id: str, start: Optional[float] = None, stop: Optional[float] = None,
                       every: Optional[int] = None) -> str:
        """The trajectory as the CSV text `moreau run --out` writes."""
        return self._bytes("/v1/jobs/%s/trajectory" % job_id,
                           {"format": "csv", "from": start, "to": stop, "every": every}).decode("utf-8")

    def figure(self, job_id: str, kind: str = "state", format: str = "png", width: Optional[int] = None,
               height: Optional[int] = None, path: Union[str, "os.PathLike[str]", None] = None) -> bytes:
        """A figure of the run (kind: state, energy, step, phase, tracking) as PNG or SVG bytes; with `path`,
        also written to that file."""
        return self._figure("/v1/jobs/%s/figure" % job_id, kind, format, width, height, path)

    def events(self, job_id: str, last_event_id: Optional[int] = None) -> Iterator[Event]:
        """The run's server-sent events, as Event objects, until the stream ends (after the final state).
        `last_event_id` resumes after that event."""
        return self._events("/v1/jobs/%s/events" % job_id, last_event_id)

    # -- studies --------------------------------------------------------------------------------

    def submit_study(self, scene: SceneArg, overrides: Optional[Overrides] = None, *,
                     set: Optional[Mapping[str, Any]] = None, **study: Any) -> Job:
        """Queues a study (docs/studies.md): study options h, schemes, reference_h, epsilon,
        regularization, eval_points, repeats as keyword arguments; `set` and `overrides` as for submit()."""
        body: Dict[str, Any] = {"scene": _scene_value(scene)}
        assignments = _assignments({}, set, overrides)
        if assignments:
            body["overrides"] = assignments
        if study:
            body["study"] = study
        return Job(self._json("POST", "/v1/studies", body=body))

    def study(self, study_id: str, wait: Optional[float] = None) -> Job:
        return Job(self._json("GET", "/v1/studies/" + study_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def wait_study(self, study_id: str, timeout: Optional[float] = None, progress: Optional[Progress] = None) -> Job:
        return self._wait("/v1/studies/", study_id, timeout, progress)

    def run_study(self, scene: SceneArg, overrides: Optional[Overrides] = None, *, set: Optional[Mapping[str, Any]] = None,
                  timeout: Optional[float] = None, progress: Optional[Progress] = None, **study: Any) -> Job:
        """submit_study() then wait: the finished study, whose `result` holds the table and the fitted
        orders. Raises RunFailed (the Job as `result`) if it failed."""
        return _unless_failed(self.wait_study(self.submit_study(scene, overrides, set=set, **study).id, timeout, progress))

    def study_table_csv(self, study_id: str) -> str:
        return self._bytes("/v1/studies/%s/table" % study_id, {"format": "csv"}).decode("utf-8")

    def study_figure(self, study_id: str, kind: str = "work", format: str = "png", width: Optional[int] = None,
                     height: Optional[int] = None, path: Union[str, "os.PathLike[str]", None] = None) -> bytes:
        """A figure of the study (kind: work, order) as PNG or SVG bytes; with `path`, also written there."""
        return self._figure("/v1/studies/%s/figure" % study_id, kind, format, width, height, path)

    def cancel_study(self, study_id: str) -> Job:
        return Job(self._json("DELETE", "/v1/studies/" + study_id))

    def study_events(self, study_id: str, last_event_id: Optional[int] = None) -> Iterator[Event]:
        return self._events("/v1/studies/%s/events" % study_id, last_event_id)

    # -- campaigns ------------------------------------------------------------------------------

    def submit_campaign(self, scene: SceneArg, campaign: Mapping[str, Any], overrides: Optional[Overrides] = None, *,
                        set: Optional[Mapping[str, Any]] = None) -> Job:
        """Queues a robustness campaign (docs/campaigns.md): `campaign` is a spec without its scene
        ({"inputs": [...], "sampler": ..., "samples": ..., "seed": ..., "target": ..., ...}); `scene` as
        for submit()."""
        body: Dict[str, Any] = {"scene": _scene_value(scene), "campaign": dict(campaign)}
        assignments = _assignments({}, set, overrides)
        if assignments:
            body["overrides"] = assignments
        return Job(self._json("POST", "/v1/campaigns", body=body))

    def campaign(self, campaign_id: str, wait: Optional[float] = None) -> Job:
        """The campaign; its `summary` (success rate and interval, quantiles, worst samples, rank
        correlations) once done, and `progress` {samples, samples_total, fraction}."""
        return Job(self._json("GET", "/v1/campaigns/" + campaign_id, {"wait": wait}, timeout=(wait or 0) + self.timeout))

    def wait_campaign(self, campaign_id: str, timeout: Optional[float] = None, progress: Optional[Progress] = None) -> Job:
        return self._wait("/v1/campaigns/", campaign_id, timeout, progress)

    def run_campaign(self, scene: SceneArg, campaign: Mapping[str, Any], overrides: Optional[Overrides] = None, *,
                     set: Optional[Mapping[str, Any]] = None, timeout: Optional[float] = None,
                     progress: Optional[Progress] = None) -> Job:
        """submit_campaign() then wait: the finished campaign, with its `summary`. Raises RunFailed (the
        Job as `result`) if it failed."""
        job = self.submit_campaign(scene, campaign, overrides, set=set)
        return _unless_failed(self.wait_campaign(job.id, timeout, progress))

    def campaign_samples(self, campaign_id: str) -> List[Dict[str, Any]]:
        """The records of the samples that finished (also of a cancelled campaign), one dict per sample, in
        the order they finished."""
        text = self._bytes("/v1/campaigns/%s/samples" % campaign_id, {"format": "jsonl"}).decode("utf-8")
        return [json.loads(line) for line in text.splitlines() if line]

    def campaign_samples_csv(self, campaign_id: str) -> str:
        return self._bytes("/v1/campaigns/%s/samples" % campaign_id, {"format": "csv"}).decode("utf-8")

    def campaign_figure(self, campaign_id: str, kind: str = "convergence-cdf", format: str = "png",
                        width: Optional[int] = None, height: Optional[int] = None,
                        path: Union[str, "os.PathLike[str]", None] = None) -> bytes:
        """A figure of the campaign (kind: convergence-cdf, inputs, success-map) as PNG or SVG bytes."""
        return self._figure("/v1/campaigns/%s/figure" % campaign_id, kind, format, width, height, path)

    def cancel_campaign(self, campaign_id: str) -> Job:
        return Job(self._json("DELETE", "/v1/campaigns/" + campaign_id))

    def campaign_events(self, campaign_id: str, last_event_id: Optional[int] = None) -> Iterator[Event]:
        return self._events("/v1/campaigns/%s/events" % campaign_id, last_event_id)

    # -- helpers --------------------------------------------------------------------------------

    def _figure(self, path: str, kind: str, format: str, width: Optional[int], height: Optional[int],
                file: Union[str, "os.PathLike[str]", None]) -> bytes:
        data = self._bytes(path, {"kind": kind, "format": format, "width": width, "height": height})
        if file is not None:
            with open(file, "wb") as f:
                f.write(data)
        return data

    def _wait(self, prefix: str, job_id: str, timeout: Optional[float], progress: Optional[Progress]) -> Job:
        deadline = None if timeout is None else time.monotonic() + timeout
        last: Optional[int] = None
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
                for event in self._events(prefix + job_id + "/events", last,
                                          timeout=left if deadline is not None else None, raw_timeouts=True):
                    last = event.id
                    if event.name in ("progress", "state"):
                        progress(Job(self._json("GET", prefix + job_id)))
                    if deadline is not None and time.monotonic() > deadline:
                        break
            except (socket.timeout, TimeoutError):
                if deadline is None or time.monotonic() < deadline:
                    raise ServerUnreachable(self.url, "the event stream timed out") from None
            job = Job(self._json("GET", prefix + job_id))
            if job.final:
                return job

    def _events(self, path: str, last_event_id: Optional[int], timeout: Optional[float] = None,
                raw_timeouts: bool = False) -> Iterator[Event]:
        headers = {"Accept": "text/event-stream"}
        if last_event_id is not None:
            headers["Last-Event-ID"] = str(last_event_id)
        r = self._open("GET", path, headers=headers, timeout=timeout or max(self.timeout, 30.0), raw_timeouts=raw_timeouts)
        with r:
            event_id: Optional[int] = None
            name, data = "message", []  # type: str, List[str]
            lines = iter(r)
            while True:
                try:
                    raw = next(lines)
                except StopIteration:
                    return
                except (OSError, http.client.HTTPException) as e:
                    if raw_timeouts and isinstance(e, socket.timeout):
                        raise
                    raise ServerUnreachable(self.url, "the event stream broke off: %s: %s" % (type(e).__name__, e)) from None
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


def _kinds(kind: Optional[str]) -> Tuple[str, ...]:
    if kind is None:
        return KINDS
    if kind not in KINDS:
        raise ValueError("kind must be run, study, campaign or None (all three), not %r" % (kind,))
    return (kind,)


def _created(job: Job) -> Tuple[float, str]:
    return (float(job.raw.get("created") or 0), job.id)


def _unless_failed(job: Job) -> Job:
    if job.state == "failed":
        if job.strict_failure:
            raise HypothesisFailed(job.reason or "a hypothesis fails", job)
        what = {"study": "study", "campaign": "campaign"}.get(job.kind, "run")
        raise RunFailed("the %s %s failed: %s" % (what, job.id, job.reason or ""), job)
    return job


def _scene_value(scene: SceneArg) -> Any:
    """The request's `scene`: a dict as it is, a file's contents, or a shipped scene's name."""
    if isinstance(scene, Mapping):
        return dict(scene)
    if isinstance(scene, os.PathLike):
        with open(scene, encoding="utf-8") as f:
            return json.load(f)
    if isinstance(scene, str):
        if scene.endswith(".json") or "/" in scene or os.sep in scene:
            raise ValueError("%r looks like a file: pass pathlib.Path(%r) to send a scene file (a str is the name "
                             "of one of the server's shipped scenes, Client.scenes())" % (scene, scene))
        return scene
    raise TypeError("scene must be a dict, a pathlib.Path to a scene file, or the name (str) of a shipped scene, "
                    "not %s" % type(scene).__name__)


def _pointer_token(key: str) -> str:
    return key.replace("~", "~0").replace("/", "~1")


def _flatten_patch(patch: Mapping[str, Any], prefix: str, out: List[Tuple[str, Any]]) -> None:
    """A JSON merge patch (RFC 7396) as assignments of its leaves, by JSON pointer: {"integrator": {"h":
    1e-4}} sets /integrator/h alone. A list or any other non-object replaces the member, as in a merge
    patch. A null, which in a merge patch removes the member, is refused: the server's overrides set
    members and remove none."""
    for key, value in patch.items():
        if not isinstance(key, str):
            raise TypeError("a scene patch's keys are strings, not %r" % (key,))
        pointer = prefix + "/" + _pointer_token(key)
        if isinstance(value, Mapping):
            _flatten_patch(value, pointer, out)
        elif value is None:
            raise ValueError("%s: None (null) would remove the member in a merge patch, which the server cannot do: "
                             "edit the scene dict instead" % pointer)
        else:
            out.append((pointer, value))


def _assignments(patch: Mapping[str, Any], set: Optional[Mapping[str, Any]],
                 overrides: Optional[Overrides]) -> List[str]:
    """The request's `overrides`, in order: the patch's leaves, then `set`, then `overrides`, each as
    "PATH=VALUE" with the value as JSON (the server applies them in order)."""
    pairs: List[Tuple[str, Any]] = []
    _flatten_patch(patch, "", pairs)
    if set is not None:
        if not isinstance(set, Mapping):
            raise TypeError("set must be a dict {path: value}, e.g. set={\"integrator.h\": 1e-4}")
        pairs += list(set.items())
    # The values as JSON, as a run in process writes them (moreau.overrides: NaN refused by its pointer).
    out = [assignment for path, value in pairs for assignment in set_list({path: value})]
    if overrides is not None:
        if not isinstance(overrides, (Mapping, list, tuple)):
            raise TypeError("overrides must be a dict {path: value} or a list of \"PATH=VALUE\" strings")
        out += set_list(overrides)
    return out


def _split_columns(columns: Sequence[str]) -> Tuple[int, List[str]]:
    """n (the coordinates) and the signal names of a trajectory's columns t, h, q (n), v (n), energy,
    signals: "energy" is a reserved name, so its place gives n."""
    try:
        e = list(columns).index("energy")
    except ValueError:
        raise ValueError("a trajectory without an energy column: %s" % ", ".join(columns)) from None
    if e < 2 or (e - 2) % 2:
        raise ValueError("unexpected trajectory columns: %s" % ", ".join(columns))
    return (e - 2) // 2, list(columns[e + 1:])


def _read_exactly(r: Any, view: memoryview) -> None:
    got = 0
    while got < len(view):
        n = r.readinto(view[got:])
        if not n:
            raise http.client.IncompleteRead(bytes(view[:got]), len(view) - got)
        got += n


_NPY_HEADER = re.compile(r"\{'descr': '<f8', 'fortran_order': False, 'shape': \((\d{1,15}), (\d{1,6}),?\), *\} *\n?")


def _read_npy(np_: Any, r: Any) -> "np.ndarray":
    """A .npy body (version 1.0, one 2-D little-endian float64 array in C order, as the server writes it)
    read from the answer straight into the array's memory: the header first, then the values with
    readinto, no copy in between. The header is matched as text, never evaluated."""
    prefix = bytearray(10)
    _read_exactly(r, memoryview(prefix))
    if bytes(prefix[:8]) != b"\x93NUMPY\x01\x00":
        raise ValueError("not an .npy file of version 1.0")
    header = bytearray(int.from_bytes(prefix[8:10], "little"))  # at most 65535 bytes
    _read_exactly(r, memoryview(header))
    m = _NPY_HEADER.fullmatch(header.decode("latin1"))
    if m is None:
        raise ValueError("an .npy of an unexpected array: %r" % bytes(header[:200]))
    table = np_.empty((int(m.group(1)), int(m.group(2))), dtype="<f8")
    if table.size:
        _read_exactly(r, memoryview(table).cast("B"))
    if r.read(1):
        raise ValueError("the .npy answer is longer than its array")
    return table


def _numpy() -> Any:
    try:
        import numpy
    except ImportError:
        return None
    return numpy
