"""The published values of Zohdi (2021), Tables 1-3, as data (for `warp-ricochet report --paper`).

Source: T. I. Zohdi, "DEM modeling and simulation of post-impact shotgun pellet ricochet for safety
analysis", Mathematics and Mechanics of Solids (2021), doi:10.1177/10812865211011217, section 3
(450 steel pellets, D = 0.0025 m, rho = 7000 kg/m^3, |v0| = 411.46 m/s, E = 0.01, mu_d = 0.9 mu_s).
Every number below is transcribed as printed, one tuple per printed row, in the paper's order
(mu_s = 0.5 first).

Notes on reading the tables:

- The "Time" column of Tables 1 and 2 holds 0.000 for the pre-impact row and 0.010 for the
  post-impact row of each mu_s. The paper states no unit for it and gives no impact duration
  delta t elsewhere, so it is only a pre/post label here (`TIME_PRE`, `TIME_POST`); our reports
  print "pre" / "post" instead.
- Table 2's energy headers read "<W_T>_N mu (J)" in the source; the values are in J (m |v0|^2 / 2
  of a 0.0025 m steel pellet at 411.46 m/s is 4.85 J), and the two ratio columns are the pre/post
  energies over the mean launch energy <W(t=0)>.
- The stick rows (mu_s >= 0.1) do not follow from the paper's own stick law, eqs. (27)-(29): with
  no incoming spin, eq. (29) gives v_t(t + dt) = (1 - 2/7) v_t(t) = 5/7 * 290.454 = 207.47 m/s
  and eq. (28) gives |omega| = (5/7) v_t / R, about 1.66e5 rad/s, whereas Table 1 prints 36.950 m/s
  and 29,880.239 rad/s (and Table 3 ranges of about 22 m accordingly). The slip rows do follow
  eqs. (31)-(34). Expect our stick rows to differ from the paper's; compare slip rows and trends.
- Table 3 counts are not given: its "Frictional case" column is only "All-stick", "All-slip" or
  "Mixed: stick+slip".
"""

from __future__ import annotations

__all__ = ["TABLE1", "TABLE2", "TABLE3", "TIME_PRE", "TIME_POST", "MU_D_FACTOR", "PAPER_ROWS", "paper_row"]

TIME_PRE = 0.000  # the "Time" printed on pre-impact rows (a label; see the module docstring)
TIME_POST = 0.010  # the "Time" printed on post-impact rows
MU_D_FACTOR = 0.9  # mu_d = 0.9 mu_s throughout the study

# Table 1. Pre- and post-impact velocities.
# (mu_s, Time, <v_c,t>_N (m/s), <v_c,n>_N (m/s), ||<omega>_N|| (rad/s))
TABLE1 = (
    (0.500, 0.000, 290.454, -290.959, 0.000),
    (0.500, 0.010, 36.950, 2.892, 29880.239),
    (0.450, 0.000, 290.454, -290.959, 0.000),
    (0.450, 0.010, 36.950, 2.892, 29880.239),
    (0.400, 0.000, 290.454, -290.959, 0.000),
    (0.400, 0.010, 36.950, 2.892, 29880.239),
    (0.350, 0.000, 290.454, -290.959, 0.000),
    (0.350, 0.010, 36.950, 2.892, 29880.239),
    (0.300, 0.000, 290.454, -290.959, 0.000),
    (0.300, 0.010, 36.950, 2.892, 29880.239),
    (0.250, 0.000, 290.454, -290.959, 0.000),
    (0.250, 0.010, 36.950, 2.892, 29880.239),
    (0.200, 0.000, 290.454, -290.959, 0.000),
    (0.200, 0.010, 36.950, 2.892, 29880.239),
    (0.150, 0.000, 290.454, -290.959, 0.000),
    (0.150, 0.010, 36.950, 2.892, 29880.239),
    (0.100, 0.000, 290.454, -290.959, 0.000),
    (0.100, 0.010, 36.950, 2.892, 29880.239),
    (0.050, 0.000, 290.454, -290.959, 0.000),
    (0.050, 0.010, 158.212, 2.892, 26223.662),
    (0.000, 0.000, 290.454, -290.959, 0.000),
    (0.000, 0.010, 290.454, 2.892, 0.000),
)

# Table 2. Spin and translational and rotational kinetic energies.
# (mu_s, Time, <W_T>_N (J), <W_R>_N (J), <W_T>_N / <W(t=0)>_N, <W_R>_N / <W(t=0)>_N)
TABLE2 = (
    (0.500, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.500, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.450, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.450, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.400, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.400, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.350, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.350, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.300, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.300, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.250, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.250, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.200, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.200, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.150, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.150, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.100, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.100, 0.010, 0.039, 0.015, 0.008, 0.003),
    (0.050, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.050, 0.010, 1.040, 0.012, 0.215, 0.002),
    (0.000, 0.000, 4.843, 0.000, 1.000, 0.000),
    (0.000, 0.010, 2.419, 0.000, 0.499, 0.000),
)

# Table 3. Post-impact ricochet ranges.
# (mu_s, <L>_N (m), L+ (m), L- (m), Frictional case)
TABLE3 = (
    (0.500, 21.888, 27.595, 17.001, "All-stick"),
    (0.450, 21.888, 27.595, 17.001, "All-stick"),
    (0.400, 21.888, 27.595, 17.001, "All-stick"),
    (0.350, 21.888, 27.595, 17.001, "All-stick"),
    (0.300, 21.888, 27.595, 17.001, "All-stick"),
    (0.250, 21.888, 27.595, 17.001, "All-stick"),
    (0.200, 21.888, 27.595, 17.001, "All-stick"),
    (0.150, 21.888, 27.595, 17.001, "All-stick"),
    (0.100, 21.888, 27.595, 17.001, "All-stick"),
    (0.050, 92.908, 164.918, 17.001, "Mixed: stick+slip"),
    (0.000, 172.016, 172.584, 169.308, "All-slip"),
)


def _build_rows() -> dict[float, dict]:
    """mu_s -> the paper's values under our statistic names (see `tallies.sums.STAT_UNITS`) plus "case"."""
    rows: dict[float, dict] = {}
    for mu_s, time, vt, vn, omega in TABLE1:
        phase = "pre" if time == TIME_PRE else "post"
        rows.setdefault(mu_s, {"mu_s": mu_s, "mu_d": round(MU_D_FACTOR * mu_s, 12)}).update(
            {f"{phase}_mean_vt": vt, f"{phase}_mean_vn": vn, f"{phase}_norm_mean_omega": omega}
        )
    for mu_s, time, wt, wr, ratio_t, ratio_r in TABLE2:
        phase = "pre" if time == TIME_PRE else "post"
        rows[mu_s].update(
            {f"{phase}_mean_WT": wt, f"{phase}_mean_WR": wr, f"{phase}_ratio_WT": ratio_t, f"{phase}_ratio_WR": ratio_r}
        )
    for mu_s, mean, longest, shortest, case in TABLE3:
        rows[mu_s].update({"range_mean": mean, "range_max": longest, "range_min": shortest, "case": case})
    return rows


PAPER_ROWS = _build_rows()


def paper_row(mu_s: float, tol: float = 1e-9) -> dict | None:
    """The paper's row for static friction `mu_s` (a copy), or None where the paper has none."""
    for key, row in PAPER_ROWS.items():
        if abs(key - float(mu_s)) <= tol:
            return dict(row)
    return None
