"""A LIGGGHTS/LAMMPS `dump custom id x y z vx vy vz radius` (gzipped) as a LAMMPS data file
(atom_style granular: id type diameter density x y z; then the velocities), so that LIGGGHTS can
start from the same configuration as am-sim's `[[import]]` of the dump. A dump carries no
tangential histories (a restart would), so both programs then start without them.

usage: python3 benches/dump_to_data.py DUMP.gz OUT.data   (density 7800 kg/m^3, in.bench's)
"""
import gzip
import sys

lines = gzip.open(sys.argv[1], "rt").read().split("\n")
n = int(lines[lines.index("ITEM: NUMBER OF ATOMS") + 1])
bounds = lines.index(next(line for line in lines if line.startswith("ITEM: BOX BOUNDS")))
(x0, x1), (y0, y1), (z0, z1) = (lines[bounds + i].split()[:2] for i in (1, 2, 3))
k = next(i for i, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
rows = [line.split() for line in lines[k + 1:k + 1 + n]]
with open(sys.argv[2], "w") as f:
    f.write(f"dump of the settled bed\n\n{n} atoms\n1 atom types\n\n{x0} {x1} xlo xhi\n"
            f"{y0} {y1} ylo yhi\n{z0} {z1} zlo zhi\n\nAtoms\n\n")
    for r in rows:
        f.write(f"{r[0]} 1 {2 * float(r[7]):.6e} 7800 {r[1]} {r[2]} {r[3]}\n")
    f.write("\nVelocities\n\n")
    for r in rows:
        f.write(f"{r[0]} {r[4]} {r[5]} {r[6]} 0 0 0\n")
