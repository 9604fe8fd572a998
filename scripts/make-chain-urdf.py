#!/usr/bin/env python3
"""Writes the URDF of an n-link planar chain: n revolute joints about z, link k a uniform rod of length L
and mass m along the x axis of its frame (centre of mass at L/2, inertia m L^2 / 12 about z, a thin rod's
m L^2 / 1200 about x), each joint at the tip of the previous link. Gravity is the scene's to set (the
chain swings in the x-y plane for gravity along -y).

Usage: make-chain-urdf.py N [--length L] [--mass M] [--limit RAD] > chain.urdf
Benchmarks and tests generate their chains with it (bench/, tests/CMakeLists.txt)."""
import argparse
import sys


def chain_urdf(n, length, mass, limit):
    rod = mass * length * length / 12.0
    thin = mass * length * length / 1200.0
    out = ['<?xml version="1.0"?>', f'<robot name="chain{n}">', '  <link name="base"/>']
    for k in range(1, n + 1):
        parent = "base" if k == 1 else f"link{k - 1}"
        x = 0.0 if k == 1 else length
        joint = "continuous" if limit is None else "revolute"
        out += [f'  <joint name="joint{k}" type="{joint}">', f'    <parent link="{parent}"/>', f'    <child link="link{k}"/>',
                f'    <origin xyz="{x!r} 0 0" rpy="0 0 0"/>', '    <axis xyz="0 0 1"/>']
        if limit is not None:
            out.append(f'    <limit lower="{-limit!r}" upper="{limit!r}" effort="100" velocity="10"/>')
        out += ['  </joint>', f'  <link name="link{k}">', '    <inertial>', f'      <origin xyz="{length / 2!r} 0 0" rpy="0 0 0"/>',
                f'      <mass value="{mass!r}"/>',
                f'      <inertia ixx="{thin!r}" ixy="0" ixz="0" iyy="{rod!r}" iyz="0" izz="{rod!r}"/>', '    </inertial>', '  </link>']
    out += ['</robot>', '']
    return "\n".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("n", type=int, help="number of links and joints, 1 to 1024")
    p.add_argument("--length", type=float, default=0.1, help="link length, m (default 0.1)")
    p.add_argument("--mass", type=float, default=0.1, help="link mass, kg (default 0.1)")
    p.add_argument("--limit", type=float, default=None, help="joint limits +-RAD (default: continuous joints, no limits)")
    p.add_argument("-o", "--output", help="write here instead of stdout")
    a = p.parse_args()
    if not 1 <= a.n <= 1024 or not a.length > 0 or not a.mass > 0:
        p.error("need 1 <= n <= 1024, length > 0 and mass > 0")
    text = chain_urdf(a.n, a.length, a.mass, a.limit)
    if a.output:
        with open(a.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
