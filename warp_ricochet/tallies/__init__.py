"""Tallies: what a run adds up about its pellets (the statistics of section 3.1 and Tables 1-3,
and the collision totals), on the device per thread and segment, combined on the host in a fixed order."""
