"""What the seed scripts under bench/ share (bench/fixed_lrf/seeds.py, bench/boards/seeds.py):
the angle between two rotations and a run of `pingcal simulate` then `pingcal calibrate`."""
import math, os, subprocess


def rot_err_deg(a, b):
    """The angle (degrees) of a·bᵀ for two 3 × 3 rotations given as nested lists."""
    m = [[sum(a[i][k] * b[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    c = max(-1.0, min(1.0, (m[0][0] + m[1][1] + m[2][2] - 1) / 2))
    return math.degrees(math.acos(c))


def simulate_and_calibrate(binary, work, seed, config):
    """`pingcal simulate` of `config` with `seed` into WORK/pSEED, then `pingcal calibrate`
    into WORK/oSEED (doubtful accepted); the project's and the output's folders and the
    calibration's completed process."""
    p, o = os.path.join(work, f"p{seed}"), os.path.join(work, f"o{seed}")
    subprocess.run([binary, "simulate", "--out", p, "--seed", str(seed), "--config", config],
                   check=True, capture_output=True)
    r = subprocess.run([binary, "calibrate", os.path.join(p, "project.toml"), "--out", o,
                        "--quiet", "--accept-doubtful"], capture_output=True, text=True)
    return p, o, r
