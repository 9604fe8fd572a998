"""Moreau: simulation of nonsmooth dynamical systems (set-valued controllers, Coulomb friction, relays,
unilateral contacts with impacts), in process or on a server. docs/python.md walks through it.

    import moreau
    r = moreau.run("scenes/manipulator.json", integrator={"h": 1e-4})
    r.t, r.q, r.v, r.energy              # numpy arrays (views of the run's own memory)
    print(r.report_text)                 # what `moreau run` prints
    png = r.figure("state")              # the command line's figures

    remote = moreau.Client("http://127.0.0.1:8080")
    r = remote.run(pathlib.Path("scenes/manipulator.json"), integrator={"h": 1e-4})   # the same Result
"""

from .errors import HypothesisFailed, MoreauError, RunFailed, SceneError, ServerError, ServerUnreachable
from .local import Campaign, Scene, Study, campaign, load, run, study
from .result import Result

__version__ = "0.1.0"

__all__ = ["load", "run", "study", "campaign", "Scene", "Result", "Study", "Campaign", "Client", "MoreauError",
           "SceneError", "RunFailed", "HypothesisFailed", "ServerError", "ServerUnreachable"]


def __getattr__(name: str):
    # The HTTP client is imported at its first use: `import moreau` for local runs loads no socket code.
    if name == "Client":
        from .client import Client
        return Client
    raise AttributeError("module 'moreau' has no attribute %r" % name)
