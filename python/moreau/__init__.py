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

import os as _os
import pathlib as _pathlib

# Installed (cmake --install), the package sits in <prefix>/lib/python3.X/dist-packages/moreau and the
# modules the scene library and the renderer open at their first use in <prefix>/lib/moreau: the same
# environment variables that point the command line at them point the compiled part there
# (platform/include/moreau/platform/install_paths.h). From the build tree, the paths it was built with
# serve.
for _variable, _file in (("MOREAU_URDF_MODULE", "libmoreau_urdf.so"), ("MOREAU_RENDER_GL", "libmoreau_render_gl.so")):
    _installed = _pathlib.Path(__file__).resolve().parents[3] / "moreau" / _file
    if _variable not in _os.environ and _installed.is_file():
        _os.environ[_variable] = str(_installed)

from .errors import HypothesisFailed, MoreauError, RunFailed, SceneError, ServerError, ServerSceneError, ServerUnreachable
from .local import Campaign, Scene, Study, campaign, load, run, study
from .result import Result

__version__ = "0.1.0"

__all__ = ["load", "run", "study", "campaign", "Scene", "Result", "Study", "Campaign", "Client", "MoreauError",
           "SceneError", "RunFailed", "HypothesisFailed", "ServerError", "ServerSceneError", "ServerUnreachable"]


def __getattr__(name: str):
    # The HTTP client is imported at its first use: `import moreau` for local runs loads no socket code.
    if name == "Client":
        from .client import Client
        return Client
    raise AttributeError("module 'moreau' has no attribute %r" % name)
