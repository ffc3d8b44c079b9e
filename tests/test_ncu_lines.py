"""`bench.ncu_lines` reads Nsight Compute's per-line source CSV (`--print-source cuda,sass`): the
per-line rows of each file, their totals and active lanes (thread over warp instructions)."""

from bench.ncu_lines import read, report

HEADER = '"Line No","Source","Address","Source","Warp Stall Sampling (All Samples)","Warp Stall Sampling (Not-issued Samples)","# Samples","Instructions Executed","Thread Instructions Executed"'
PAGE = f""""File Path","/x/warp_ricochet/tallies/path.py"
"Function Name","ricochet_kernel"
{HEADER}
"12","level += 1","-","-","30","20","30","100","400"
"","","0x7f00","  IADD3 R1, R2, R3","30","20","30","100","400"
"13","return level","-","-","10","5","10","50","1600"
"File Path","/x/warp_ricochet/physics/air.py"
"Function Name","ricochet_kernel"
{HEADER}
"7","drag = c * v","-","-","60","40","60","850","27200"
"""


def test_lines_and_their_lanes_are_read_per_file(tmp_path):
    path = tmp_path / "source.csv"
    path.write_text(PAGE)
    rows = read(str(path))
    assert set(rows) == {("path.py", 12), ("path.py", 13), ("air.py", 7)}  # the SASS rows are not lines
    assert rows["path.py", 13] == {"src": "return level", "samples": 10.0, "inst": 50.0, "thr": 1600.0}
    text = report(rows, "inst", 2)
    assert text.splitlines()[0].startswith("warp instructions 1.000e+03, thread instructions 2.920e+04, active lanes 29.20")
    assert "path.py                          inst  15.0%" in text and "lanes 13.33" in text  # 2,000 / 150
    assert text.splitlines()[-1].startswith("path.py                 :   12 inst 10.00% lanes  4.00")
