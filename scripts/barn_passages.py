"""Each BARN world's widest passage from start to goal (``bulletnav.barn.passage``), against the
Jackal's width and turning diameter: which worlds any controller can cross without a touch.

    .venv/bin/python scripts/barn_passages.py test docs/results/barn_passages_test.json
    .venv/bin/python scripts/barn_passages.py 9,81,93 runs/passages.json

WORLDS is ``test``, ``train``, ``all`` or a comma-separated list of indices. The record holds the
command, commit and machine (``bulletnav.provenance``) beside the rows.
"""

from __future__ import annotations

import sys

from bulletnav.barn.data import N_WORLDS, POOLS
from bulletnav.barn.passage import BARN_BOUNDS, passage_table
from bulletnav.config import EnvConfig, robot_preset
from bulletnav.files import write_json
from bulletnav.geometry import robot_geometry
from bulletnav.provenance import provenance


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    spec, out = argv
    worlds = list(range(N_WORLDS)) if spec == "all" else list(POOLS[spec]) if spec in POOLS else [int(w) for w in spec.split(",")]
    geometry = robot_geometry(robot_preset(EnvConfig(), "jackal").robot)
    width = 2 * geometry.half_width
    turning = 2 * geometry.outline_radius  # the circle the outline sweeps turning in place
    rows = passage_table(worlds, width)
    for r in rows:
        r["fits_turning"] = r["widest_passage_m"] >= turning
    narrow = [r for r in rows if r["room_m"] < 0]
    write_json(out, {"what": "widest passage from BARN's start to its goal (m): twice the largest clearance at which they "
                             "are connected (bulletnav.barn.passage, 1 cm grid)", "bounds_m": BARN_BOUNDS,
                     "robot": "jackal", "robot_width_m": round(width, 3), "turning_diameter_m": round(turning, 3),
                     "worlds": len(rows), "narrower_than_robot": [r["world"] for r in narrow], "rows": rows, **provenance()})
    print(f"{len(rows)} worlds; widest passage min {min(r['widest_passage_m'] for r in rows):.3f} m, "
          f"median {sorted(r['widest_passage_m'] for r in rows)[len(rows) // 2]:.3f} m; Jackal width {width:.3f} m, "
          f"turning diameter {turning:.3f} m; narrower than the Jackal: {[r['world'] for r in narrow]}; "
          f"narrower than its turning diameter: {[r['world'] for r in rows if not r['fits_turning']]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
