#!/usr/bin/env python3
"""Writes scenes/robots/puma560.urdf: the 6-joint Unimation PUMA 560 (dynamics only) from its standard
Denavit-Hartenberg parameters and link inertial parameters as published in
  P. Corke and B. Armstrong-Helouvry, "A search for consensus among model parameters reported for the
  PUMA 560 robot", Proc. IEEE ICRA 1994, pp. 1608-1613 (the values of Corke's Robotics Toolbox model
  Puma560, standard DH), with joint limits from Wang and Chen, IEEE Trans. RA 7(4) 1991.
Conversion: URDF link i's frame is DH frame i-1 turned by q_i about its z axis, so joint i sits at
(a_{i-1}, 0, d_{i-1}) with rpy (alpha_{i-1}, 0, 0) in link i-1 and turns about z; link i's centre of mass
r_i and inertia (about the centre of mass, in DH frame i) become an <inertial> at
(a_i, 0, d_i) + Rx(alpha_i) r_i with rpy (alpha_i, 0, 0).
Deviations from the published table, none of which changes the dynamics except the third:
  - link 1: mass 0 in the table (Armstrong found none); URDF needs a positive mass, and a mass at the
    centre of mass given, (0, 0, 0) in frame 1, which lies on joint 1's axis, adds nothing to M(q) or to
    the gravity torque, so 1 kg is written. Its table inertia is (0, 0.35, 0): only I_yy (about joint 1's
    axis) enters the dynamics; I_xx = I_zz = 0.35 make the tensor physical without changing M(q).
  - link 3: the table's (0.066, 0.086, 0.0125) breaks the triangle inequality I_xx + I_zz >= I_yy
    (0.0785 < 0.086), which no rigid body can; I_zz is raised to 0.020 (the smallest round value that
    satisfies it). This changes M(q) slightly.
  - friction: the table gives motor-side viscous B and Coulomb Tc (per direction) and gear ratios G; the
    joint-side values written in <dynamics> are B G^2 and the mean of |Tc| times |G|. Rotor inertias
    Jm G^2 are not in URDF and are left out.
Usage: make-puma560-urdf.py [-o FILE]"""
import argparse
import math

# d, a, alpha, mass, r (in DH frame i), I (xx, yy, zz about the centre of mass), qlim (deg), B, Tc(-, +), G
LINKS = [
    (0.672, 0.0, math.pi / 2, 0.0, (0, 0, 0), (0, 0.35, 0), (-160, 160), 1.48e-3, (0.395, -0.435), -62.6111),
    (0.0, 0.4318, 0.0, 17.4, (-0.3638, 0.006, 0.2275), (0.13, 0.524, 0.539), (-45, 225), 0.817e-3, (0.126, -0.071), 107.815),
    (0.15005, 0.0203, -math.pi / 2, 4.8, (-0.0203, -0.0141, 0.070), (0.066, 0.086, 0.0125), (-225, 45), 1.38e-3, (0.132, -0.105), -53.7063),
    (0.4318, 0.0, math.pi / 2, 0.82, (0, 0.019, 0), (1.8e-3, 1.3e-3, 1.8e-3), (-110, 170), 71.2e-6, (11.2e-3, -16.9e-3), 76.0364),
    (0.0, 0.0, -math.pi / 2, 0.34, (0, 0, 0), (0.3e-3, 0.4e-3, 0.3e-3), (-100, 100), 82.6e-6, (9.26e-3, -14.5e-3), 71.923),
    (0.0, 0.0, 0.0, 0.09, (0, 0, 0.032), (0.15e-3, 0.15e-3, 0.04e-3), (-266, 266), 36.7e-6, (3.96e-3, -10.5e-3), 76.686),
]


def rx(alpha, v):
    c, s = math.cos(alpha), math.sin(alpha)
    return (v[0], c * v[1] - s * v[2], s * v[1] + c * v[2])


def g(x):
    return repr(float(x) + 0.0)  # shortest round-trip form; + 0.0 turns -0.0 into 0.0


def urdf():
    out = ['<?xml version="1.0"?>', '<!-- Unimation PUMA 560, dynamics only; written by scripts/make-puma560-urdf.py (sources and deviations',
           '     there): Corke and Armstrong-Helouvry, ICRA 1994, standard DH. -->', '<robot name="puma560">', '  <link name="base"/>']
    for i, (d, a, alpha, m, r, inertia, qlim, B, Tc, G) in enumerate(LINKS):
        k = i + 1
        parent = "base" if i == 0 else f"link{i}"
        if i == 0:
            xyz, rpy = (0.0, 0.0, 0.0), 0.0
        else:
            pd, pa, palpha = LINKS[i - 1][0], LINKS[i - 1][1], LINKS[i - 1][2]
            xyz, rpy = (pa, 0.0, pd), palpha
        if k == 1:
            m = 1.0
            inertia = (0.35, 0.35, 0.35)
        if k == 3:
            inertia = (inertia[0], inertia[1], 0.020)
        com = rx(alpha, r)
        com = (a + com[0], com[1], d + com[2])
        damping = B * G * G
        friction = 0.5 * (abs(Tc[0]) + abs(Tc[1])) * abs(G)
        lo, hi = math.radians(qlim[0]), math.radians(qlim[1])
        out += [f'  <joint name="joint{k}" type="revolute">', f'    <parent link="{parent}"/>', f'    <child link="link{k}"/>',
                f'    <origin xyz="{g(xyz[0])} {g(xyz[1])} {g(xyz[2])}" rpy="{g(rpy)} 0 0"/>', '    <axis xyz="0 0 1"/>',
                f'    <limit lower="{g(lo)}" upper="{g(hi)}" effort="100" velocity="5"/>',
                f'    <dynamics damping="{g(damping)}" friction="{g(friction)}"/>', '  </joint>',
                f'  <link name="link{k}">', '    <inertial>',
                f'      <origin xyz="{g(com[0])} {g(com[1])} {g(com[2])}" rpy="{g(alpha)} 0 0"/>', f'      <mass value="{g(m)}"/>',
                f'      <inertia ixx="{g(inertia[0])}" ixy="0" ixz="0" iyy="{g(inertia[1])}" iyz="0" izz="{g(inertia[2])}"/>',
                '    </inertial>', '  </link>']
    out += ['</robot>', '']
    return "\n".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", help="write here instead of stdout")
    a = p.parse_args()
    text = urdf()
    if a.output:
        with open(a.output, "w") as f:
            f.write(text)
    else:
        print(text, end="")


if __name__ == "__main__":
    main()
