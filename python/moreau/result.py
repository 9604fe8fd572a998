"""A run's results, the same type for a run in process (moreau.run, Scene.run) and for a run on a server
(Client.run): code moves between the two by changing the line that makes the Result.

The trajectory is one table of float64, a row per recorded state and the columns of `moreau run --out`:
t, h, the positions, the velocities, the energy E_k = 1/2 <M(Q^k) V^k, V^k>, then the scene's signals (a
tracking run's qd_, e_, sigma_ and u_ per coordinate). `t`, `h`, `q`, `v`, `energy` and `signals` are
views of that table, not copies: for a run in process the table is the run's own buffer, shared with
numpy through the buffer protocol.
"""

from __future__ import annotations

import html
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Optional, Sequence, Union

if TYPE_CHECKING:  # numpy is needed to make a table, not to import the package (the client works without it)
    import numpy as np

__all__ = ["Result"]

# (kind, format, width, height) -> the figure's bytes.
FigureSource = Callable[[str, str, Optional[int], Optional[int]], bytes]


class Result:
    """One run: its trajectory as numpy arrays, its report (a dict, as `moreau run --json` prints it, and
    the text `moreau run` prints) and its figures.

    `report` and `report_text` may be given as functions of no argument: they are then called at the first
    use only, so that a loop of many runs that reads only the arrays does not build reports it never reads."""

    # For a run on a server (Client.run, Client.result): the server's moreau.client.Job (its id, state,
    # reason); None for a run in process.
    job: Optional[Any] = None

    def __init__(self, table: np.ndarray, position_names: Sequence[str], velocity_names: Sequence[str],
                 signal_names: Sequence[str], report: Union[Dict[str, Any], Callable[[], Dict[str, Any]]],
                 report_text: Union[None, str, Callable[[], str]] = None,
                 figure_source: Optional[FigureSource] = None) -> None:
        n, m = len(position_names), len(signal_names)
        if table.ndim != 2 or table.shape[1] != 3 + 2 * n + m:
            raise ValueError("a trajectory table of %d columns needs %d (t, h, %d positions, %d velocities, energy, %d signals)"
                             % (table.shape[1] if table.ndim == 2 else 0, 3 + 2 * n + m, n, n, m))
        self._table = table
        self.position_names: List[str] = list(position_names)
        self.velocity_names: List[str] = list(velocity_names)
        self.signal_names: List[str] = list(signal_names)
        self._report = report
        self._report_text = report_text
        self._figure_source = figure_source

    # -- the trajectory -------------------------------------------------------------------------

    @property
    def table(self) -> np.ndarray:
        """Every column, rows of (t, h, q..., v..., energy, signals...): `columns` names them."""
        return self._table

    @property
    def columns(self) -> List[str]:
        return ["t", "h"] + self.position_names + self.velocity_names + ["energy"] + self.signal_names

    @property
    def t(self) -> np.ndarray:
        return self._table[:, 0]

    @property
    def h(self) -> np.ndarray:
        """The step that led to each state (the first: the nominal h)."""
        return self._table[:, 1]

    @property
    def q(self) -> np.ndarray:
        """Positions, one column per coordinate (position_names)."""
        n = len(self.position_names)
        return self._table[:, 2:2 + n]

    @property
    def v(self) -> np.ndarray:
        """Velocities, one column per coordinate (velocity_names)."""
        n = len(self.position_names)
        return self._table[:, 2 + n:2 + 2 * n]

    @property
    def energy(self) -> np.ndarray:
        """E_k = 1/2 <M(Q^k) V^k, V^k> (a Lur'e system: its storage function)."""
        return self._table[:, 2 + 2 * len(self.position_names)]

    @property
    def signals(self) -> np.ndarray:
        """The scene's signals (signal_names), one column each; no columns for most scenes."""
        return self._table[:, 3 + 2 * len(self.position_names):]

    def column(self, name: str) -> np.ndarray:
        """One column by its name in `columns` ("t", "x1", "th2_dot", "energy", "e_x1", ...)."""
        try:
            return self._table[:, self.columns.index(name)]
        except ValueError:
            raise KeyError("no column %r (the columns are %s)" % (name, ", ".join(self.columns))) from None

    def __len__(self) -> int:
        return self._table.shape[0]

    def to_pandas(self) -> "Any":
        """The table as a pandas DataFrame indexed by t (needs pandas; the data is copied once)."""
        try:
            import pandas
        except ImportError:
            raise ImportError("Result.to_pandas() needs pandas (Debian: python3-pandas)") from None
        frame = pandas.DataFrame(self._table, columns=self.columns)
        return frame.set_index("t")

    # -- the report -----------------------------------------------------------------------------

    @property
    def report(self) -> Dict[str, Any]:
        """The report as `moreau run --json` prints it: status, convergence, energy, guarantees, ..."""
        if callable(self._report):
            self._report = self._report()
        return self._report

    @property
    def status(self) -> str:
        """"completed", "failed" or "cancelled"."""
        return self.report["status"]

    @property
    def converged(self) -> bool:
        """Whether the report calls the run converged (finite-step rest to the end at an equilibrium)."""
        return self.report.get("converged_step") is not None

    @property
    def guarantees(self) -> List[Dict[str, Any]]:
        """The report's guarantees: each theorem with its verdict and its hypotheses, checked on this run."""
        return self.report.get("guarantees", [])

    @property
    def report_text(self) -> str:
        """The report as `moreau run` prints it (for a remote run: the JSON report, as text)."""
        if self._report_text is None:
            import json
            return json.dumps(self.report, indent=2)
        if callable(self._report_text):
            self._report_text = self._report_text()
        return self._report_text

    # -- figures --------------------------------------------------------------------------------

    def figure(self, kind: str = "state", format: str = "png", width: Optional[int] = None, height: Optional[int] = None,
               robust_y: bool = False) -> bytes:
        """Figure `kind` (state, energy, step, phase, tracking) as PNG or SVG bytes, drawn by the same
        renderer as `moreau run --figure`. `robust_y` (a run in process, as --robust-y): the state figure's
        y axes over the 1st to 99th percentile of their values, a spike clipped and counted in the legend."""
        if self._figure_source is None:
            raise RuntimeError("this result has no figures")
        if robust_y:
            return self._figure_source(kind, format, width, height, robust_y=True)  # type: ignore[call-arg]
        return self._figure_source(kind, format, width, height)

    # -- notebooks ------------------------------------------------------------------------------

    def _repr_html_(self) -> str:
        return "<pre>" + html.escape(self.report_text) + "</pre>"

    def _repr_png_(self) -> Optional[bytes]:
        if self._figure_source is None:
            return None
        return self.figure("tracking" if self.signal_names else "state", "png", 900, 600)

    def __repr__(self) -> str:
        return "<moreau.Result %s: %d rows of %s, status %s>" % (
            self.report.get("scene", "?"), len(self), ", ".join(self.columns[:6]) + (", ..." if len(self.columns) > 6 else ""),
            self.report.get("status", "?"))
