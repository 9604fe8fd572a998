"""`cmake --install` puts the package into python3's site-packages under the prefix, beside the modules it
opens (lib/moreau/), and it runs from there: a URDF scene (the URDF module) and a PNG figure (the raster
module), both opened from the installed tree."""

import os
import pathlib
import subprocess
import sys

CHILD = r"""
import json, sys, moreau
r = moreau.run(sys.argv[1])
png = r.figure("state", width=300, height=200)
maps = [line.split()[-1] for line in open("/proc/self/maps") if "libmoreau" in line]
print(json.dumps({"package": moreau.__file__, "png": png[:8].hex(), "status": r.status, "maps": sorted(set(maps))}))
"""


def test_the_installed_package_runs_a_urdf_scene_and_draws_from_the_installed_tree(source_dir, tmp_path):
    build = pathlib.Path(os.environ["MOREAU_BUILD_DIR"])
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(build), "--prefix", str(prefix)], capture_output=True, check=True)
    site = prefix / "lib" / ("python%d.%d" % sys.version_info[:2]) / "dist-packages"
    assert (site / "moreau" / "__init__.py").is_file()
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOREAU_") and k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    out = subprocess.run([sys.executable, "-c", CHILD, str(source_dir / "scenes" / "iiwa14-controller.json")],
                         capture_output=True, text=True, env=env, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    got = __import__("json").loads(out.stdout)
    assert pathlib.Path(got["package"]).is_relative_to(site)
    assert got["status"] == "completed" and got["png"] == "89504e470d0a1a0a"
    lib = prefix / "lib" / "moreau"
    assert str(lib / "libmoreau_urdf.so") in got["maps"] and str(lib / "libmoreau_render_gl.so") in got["maps"], got["maps"]
    assert all(pathlib.Path(p).is_relative_to(prefix) for p in got["maps"]), got["maps"]
