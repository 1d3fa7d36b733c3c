#!/usr/bin/env python3
"""Write the benchmark pile of cubes as one OBJ (one object per cube, Y up).

    scripts/make_pile.py OUT.obj [--size 0.2] [--gap 0.05] [--lift 0.05] [--grid 5 4 3]

Cubes of `size` metres stand `grid[0]` × `grid[1]` in plan, `gap` apart, in `grid[2]` layers
`lift` above each other (docs/benchmarks.md: "60 cubes in a pile" is the default, and
`--gap 0.01` the tighter one). Bake it with
`springbake bake OUT.obj --cells 3 --frames 24`.
"""
import argparse

# Corner k of a cube is (k >> 2 & 1, k >> 1 & 1, k & 1) along (x, y, z); faces wound
# counter-clockwise seen from outside.
QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--size", type=float, default=0.2)
    parser.add_argument("--gap", type=float, default=0.05)
    parser.add_argument("--lift", type=float, default=0.05)
    parser.add_argument("--grid", type=int, nargs=3, default=[5, 4, 3])
    args = parser.parse_args()
    s, lines, n = args.size, [], 0
    nx, nz, ny = args.grid
    for i in range(nx):
        for j in range(nz):
            for k in range(ny):
                x0, y0, z0 = i * (s + args.gap), k * (s + args.lift), j * (s + args.gap)
                lines.append(f"o cube{n // 8 + 1}")
                for c in range(8):
                    x, y, z = (c >> 2 & 1) * s, (c >> 1 & 1) * s, (c & 1) * s
                    lines.append(f"v {x0 + x:g} {y0 + y:g} {z0 + z:g}")
                for q in QUADS:
                    lines.append("f " + " ".join(str(n + 1 + c) for c in q))
                n += 8
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
