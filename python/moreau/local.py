"""Moreau in process: scenes loaded, run, studied and swept by the compiled part (moreau._moreau), which
is the command line's own code. No server, no files but those asked for.

    scene = moreau.load("scenes/manipulator.json")
    r = scene.run(integrator={"h": 1e-4})            # or set={"integrator.h": 1e-4}
    r.t, r.q, r.v, r.energy                           # numpy views of the run's own table
"""

from __future__ import annotations

import json
import math
import numbers
import os
import pathlib
import warnings
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

if TYPE_CHECKING:
    import numpy as np

from .errors import HypothesisFailed, RunFailed
from .overrides import Sets, json_text as _json_text, set_list as _set_list
from .result import Result

try:
    from . import _moreau
except ImportError as _error:  # the pure-Python parts (the HTTP client) work without it
    _moreau = None
    _import_error: Optional[ImportError] = _error
else:
    _import_error = None

__all__ = ["Scene", "load", "run", "study", "campaign", "Study", "Campaign"]

SceneSource = Union[str, "os.PathLike[str]", Mapping[str, Any]]
Progress = Union[None, bool, Callable[..., Any]]


def _compiled() -> Any:
    if _moreau is None:
        raise ImportError("moreau's compiled part (moreau._moreau) is not built or not on the path: build the project "
                          "(it is built when Debian's python3-dev and pybind11-dev are installed) and put build/python on "
                          "PYTHONPATH, or install it with cmake --install (docs/python.md)") from _import_error
    return _moreau


def _parameter_values(sets: Sets, overrides: Mapping[str, Any]) -> Optional[Tuple[List[str], List[float]]]:
    """The (names, values) when every override only gives /parameters/<name> a number, else None."""
    names: List[str] = []
    values: List[float] = []
    for key, value in overrides.items():
        if key != "parameters" or not isinstance(value, Mapping):
            return None
        for name, number in value.items():
            if not isinstance(number, numbers.Real) or isinstance(number, bool) or not math.isfinite(number):
                return None
            names.append(str(name))
            values.append(float(number))
    if sets is not None:
        if not isinstance(sets, Mapping):
            return None
        for path, number in sets.items():
            for prefix in ("parameters.", "/parameters/"):
                if path.startswith(prefix) and "." not in path[len(prefix):] and "/" not in path[len(prefix):]:
                    break
            else:
                return None
            if not isinstance(number, numbers.Real) or isinstance(number, bool) or not math.isfinite(number):
                return None
            names.append(path[len(prefix):])
            values.append(float(number))
    if not names or len(set(names)) != len(names):
        return None
    return names, values


def _run_progress(progress: Progress, t0: float, t_end: float) -> Tuple[Optional[Callable[[float], None]], Any]:
    """The callback the run calls with t about every 50 ms, and a tqdm bar to close (or None)."""
    if progress is None or progress is False:
        return None, None
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            return None, None
        bar = tqdm(total=t_end - t0, unit="s", unit_scale=True, desc="moreau")

        def advance(t: float) -> None:
            bar.update(t - t0 - bar.n)
        return advance, bar
    return progress, None


class Scene:
    """A scene read, validated and compiled: what `moreau run` runs. Make one with moreau.load()."""

    def __init__(self, compiled: Any, source: Optional[str] = None) -> None:
        self._compiled = compiled
        self.source = source
        unread = compiled.unread_parameters
        if unread:
            warnings.warn("scene %s: parameters that nothing reads (misspelt?): %s" % (compiled.name, ", ".join(unread)), stacklevel=3)

    # -- what the scene is ----------------------------------------------------------------------

    name = property(lambda self: self._compiled.name, doc="The scene's /name.")
    system_type = property(lambda self: self._compiled.system_type, doc='"lagrangian" or "lure".')
    scheme = property(lambda self: self._compiled.scheme, doc="The scheme the scene runs (abl, moreau-jean, ...).")
    dof = property(lambda self: self._compiled.dof, doc="Coordinates (a Lur'e system: states).")
    position_names = property(lambda self: list(self._compiled.position_names))
    velocity_names = property(lambda self: list(self._compiled.velocity_names))
    signal_names = property(lambda self: list(self._compiled.signal_names), doc="A tracking scene's qd_, e_, sigma_, u_ columns.")
    t0 = property(lambda self: self._compiled.t0)
    t_end = property(lambda self: self._compiled.t_end)
    h = property(lambda self: self._compiled.h)
    planned_steps = property(lambda self: self._compiled.planned_steps)

    @property
    def document(self) -> Dict[str, Any]:
        """The scene as JSON (a copy), with the files it names read in (a URDF's text, way points)."""
        return json.loads(self._compiled.document())

    def __repr__(self) -> str:
        return "<moreau.Scene %s: %s, %d coordinates, scheme %s, h = %g, t in [%g, %g]>" % (
            self.name, self.system_type, self.dof, self.scheme, self.h, self.t0, self.t_end)

    # -- other values ---------------------------------------------------------------------------

    def with_overrides(self, set: Sets = None, **overrides: Any) -> "Scene":
        """This scene with `set` ({"integrator.h": 1e-4} or ["integrator.h=1e-4"], as `moreau run --set`)
        applied in order, then the keyword overrides merged in (a JSON merge patch: integrator={"h": 1e-4}
        changes /integrator/h and keeps the rest; None removes a member), compiled."""
        sets = _set_list(set)
        if not sets and not overrides:
            return self
        patch = _json_text(overrides) if overrides else "null"
        return Scene(self._compiled.with_overrides(sets, patch), self.source)

    # -- running --------------------------------------------------------------------------------

    def run(self, set: Sets = None, *, strict: bool = False, check: bool = True, progress: Progress = None,
            **overrides: Any) -> Result:
        """Runs the scene (with `set` and keyword overrides as in with_overrides) to t_end: a Result.

        Raises RunFailed (the command line's exit code 1) when the run ends early and `check` is true, and
        with `strict`, HypothesisFailed (exit code 3) when a hypothesis the run relies on fails. The GIL is
        released while it integrates; Ctrl-C raises KeyboardInterrupt within about 50 ms. `progress`: a
        function of t, called about every 50 ms, or True for a tqdm bar when tqdm is installed.

        A run that changes only parameters (parameters={"m1": 2.0}, or set={"parameters.m1": 2.0}) binds
        the values into the scene compiled once with those parameters free, as a campaign does, instead of
        compiling it again: the same numbers, bit for bit (scene.h, ParametricLagrangianScene)."""
        callback, bar = _run_progress(progress, self.t0, self.t_end)
        try:
            fast = _parameter_values(set, overrides)
            if fast is not None:
                out = self._compiled.run_with_parameters(fast[0], fast[1], callback)
                scene = self
            else:
                scene = self.with_overrides(set, **overrides)
                out = scene._compiled.run(callback)
        finally:
            if bar is not None:
                bar.close()
        result = _result(out, scene._compiled)
        if check and out.status != "completed":
            raise RunFailed("%s: the run %s before t_end (result.report_text says why)" % (self.name, out.status), result)
        if strict:
            failure = out.hypothesis_failure()
            if failure:
                raise HypothesisFailed("%s: %s" % (self.name, failure), result)
        return result


def _result(out: Any, compiled: Any) -> Result:
    table = out.array
    table.flags.writeable = False
    return Result(table, compiled.position_names, compiled.velocity_names, compiled.signal_names,
                  report=lambda: json.loads(out.report_json()), report_text=out.report_text,
                  figure_source=lambda kind, format, width, height, robust_y=False: out.figure(kind, format, width, height, "", robust_y))


def _document_source(scene: SceneSource) -> Tuple[str, Optional[str]]:
    """("file", path) or ("text", JSON text) for a scene given as a path or a dict."""
    if isinstance(scene, Mapping):
        return "text", _json_text(scene)
    if isinstance(scene, (str, os.PathLike)):
        return "file", os.fspath(scene)
    raise TypeError("a scene is a path (str or pathlib.Path) to a scene file, or a dict, not %s" % type(scene).__name__)


def load(scene: SceneSource, set: Sets = None, **overrides: Any) -> Scene:
    """Reads and compiles a scene: a path to a scene file (str or pathlib.Path; the files it names, a URDF
    or way points, are read relative to it) or a scene as a dict. `set` and keyword overrides as in
    Scene.with_overrides. An invalid scene raises SceneError with the JSON pointer of the field."""
    kind, value = _document_source(scene)
    compiled = _compiled()
    if kind == "file":
        c = compiled.CompiledScene.from_file(value, _set_list(set))
    else:
        c = compiled.CompiledScene.from_text(value, _set_list(set))
    if overrides:
        c = c.with_overrides([], _json_text(overrides))
    return Scene(c, value if kind == "file" else None)


def run(scene: Union[SceneSource, Scene], set: Sets = None, *, strict: bool = False, check: bool = True,
        progress: Progress = None, **overrides: Any) -> Result:
    """load(scene, set, **overrides).run(): one run of a scene file, a dict or a Scene."""
    if isinstance(scene, Scene):
        return scene.run(set, strict=strict, check=check, progress=progress, **overrides)
    return load(scene, set, **overrides).run(strict=strict, check=check, progress=progress)


# -- studies ----------------------------------------------------------------------------------------


class Study:
    """A study's result: `raw` as `moreau study --json` prints it, `rows` (a list of dicts, one per run),
    `table` (the rows' columns as numpy arrays: NaN for a value the row has not) and to_pandas()."""

    def __init__(self, raw: Dict[str, Any]) -> None:
        self.raw = raw
        self.rows: List[Dict[str, Any]] = list(raw.get("rows", []))

    @property
    def table(self) -> Dict[str, "np.ndarray"]:
        import numpy as np
        names: List[str] = []
        for row in self.rows:
            for key, value in row.items():
                if key not in names and not isinstance(value, (dict, list)):
                    names.append(key)
        out: Dict[str, "np.ndarray"] = {}
        for key in names:
            values = [row.get(key) for row in self.rows]
            if all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)) for v in values):
                out[key] = np.array([np.nan if v is None else v for v in values], dtype=float)
            else:
                out[key] = np.array(values, dtype=object)
        return out

    def to_pandas(self) -> Any:
        import pandas
        return pandas.DataFrame(self.table)

    def __getitem__(self, key: str) -> Any:
        return self.raw[key]

    def __repr__(self) -> str:
        return "<moreau.Study %s: %d rows>" % (self.raw.get("scene", "?"), len(self.rows))


def study(scene: Union[SceneSource, Scene], set: Sets = None, *, h: Optional[Sequence[float]] = None,
          schemes: Optional[Sequence[str]] = None, periods: Optional[Sequence[float]] = None,
          laws: Optional[Sequence[str]] = None, **options: Any) -> Study:
    """A study of the scene, as `moreau study` runs it (docs/studies.md): over the step sizes `h` and the
    `schemes`, with the options reference_h, epsilon, regularization, eval_points and repeats; or, for a
    tracking scene, its digital controller over the sampling `periods` and `laws` (docs/tracking.md). An
    invalid option raises SceneError naming it (/h/2, /schemes/0, ...)."""
    if isinstance(scene, Scene):
        document = scene.with_overrides(set)._compiled.document()
    else:
        document = load(scene, set)._compiled.document()
    settings: Dict[str, Any] = dict(options)
    if periods is not None:
        settings["periods"] = list(periods)
        if laws is not None:
            settings["laws"] = list(laws)
    else:
        if h is not None:
            settings["h"] = list(h)
        if schemes is not None:
            settings["schemes"] = list(schemes)
    return Study(json.loads(_compiled().study(document, _json_text(settings))))


# -- campaigns --------------------------------------------------------------------------------------


class Campaign:
    """A campaign's directory after a run: `summary` (summary.json, once every sample is present, else
    None), `summary_text`, `samples` (samples.csv as a pandas DataFrame, or a dict of numpy arrays
    without pandas), `figures` (the PNG paths), `ran`, `skipped`, `steps`."""

    def __init__(self, directory: pathlib.Path, counts: Dict[str, Any]) -> None:
        self.directory = directory
        self.ran: int = counts["ran"]
        self.skipped: int = counts["skipped"]
        self.steps: int = counts["steps"]
        self.figures: List[pathlib.Path] = [pathlib.Path(p) for p in counts["figures"]]
        summary = directory / "summary.json"
        self.summary: Optional[Dict[str, Any]] = json.loads(summary.read_text()) if summary.exists() else None
        text = directory / "summary.txt"
        self.summary_text: Optional[str] = text.read_text() if text.exists() else None

    @property
    def samples(self) -> Any:
        path = self.directory / "samples.csv"
        try:
            import pandas
        except ImportError:
            import numpy as np
            data = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
            return {name: data[name] for name in data.dtype.names}
        return pandas.read_csv(path)

    def __repr__(self) -> str:
        return "<moreau.Campaign %s: %d samples run, %d already there>" % (self.directory, self.ran, self.skipped)


def campaign(spec: Union[str, "os.PathLike[str]", Mapping[str, Any]], out: Union[str, "os.PathLike[str]"], *,
             jobs: Optional[int] = None, progress: Progress = None) -> Campaign:
    """Runs a robustness campaign (docs/campaigns.md) as `moreau campaign SPEC --out OUT -j JOBS` does:
    the same files in `out` (resumable: run it again after a Ctrl-C to go on), the figures once every
    sample is present. `spec`: a spec file's path (its scene path read relative to it) or a dict (a scene
    path in it read relative to the current directory). `jobs`:
    worker threads (default: every core). `progress`: a function of (done, total), or True for a tqdm bar
    when tqdm is installed. Ctrl-C stops after the samples running then and raises KeyboardInterrupt;
    every finished sample is kept."""
    if isinstance(spec, Mapping):
        text, base = _json_text(spec), os.getcwd()
    elif isinstance(spec, (str, os.PathLike)):
        path = pathlib.Path(spec)
        text, base = _compiled().read_scene_file(os.fspath(path)), os.fspath(path.parent)
    else:
        raise TypeError("a campaign spec is a path (str or pathlib.Path) or a dict, not %s" % type(spec).__name__)
    callback: Optional[Callable[[int, int], None]] = None
    bar = None
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            bar = tqdm(unit="sample", desc="moreau campaign")

            def callback(done: int, total: int) -> None:
                bar.total = total
                bar.update(done - bar.n)
    elif callable(progress):
        callback = progress
    try:
        counts = _compiled().campaign(text, base, os.fspath(out), int(jobs or os.cpu_count() or 1), callback)
    finally:
        if bar is not None:
            bar.close()
    return Campaign(pathlib.Path(out), counts)
