#!/usr/bin/env python3
"""Start-up guard: the `moreau` executable needs no shared library beyond the C library (README,
"Performance": each one costs page faults in every process). The HTTP, TLS and LCM libraries belong
to moreau-remote, OSMesa and libpng to the raster module, FreeType is opened at the first text.

  check_needed_libraries.py BINARY ALLOWED_SONAME...
"""
import subprocess
import sys

binary, allowed = sys.argv[1], set(sys.argv[2:])
out = subprocess.run(["readelf", "-d", binary], capture_output=True, text=True, check=True).stdout
needed = [line.split("[", 1)[1].split("]", 1)[0] for line in out.splitlines() if "(NEEDED)" in line]
extra = [n for n in needed if n not in allowed]
print(f"{binary} needs: {', '.join(needed)}")
if extra:
    print(f"not allowed: {', '.join(extra)}")
    sys.exit(1)
