#!/usr/bin/env bash
# Issue 26: a few Nsight Compute metrics of the core kernel (divergence, local memory, instructions) in
# the scene of `bench.path cost`, without and with the map. On the lent GPU: . .gpu/b/env.sh && bash bench/ncu_map_metrics.sh
# (The full section set fails to replay this kernel.) Figures: bench/RESULTS.md.
M=smsp__inst_executed.sum,smsp__thread_inst_executed_per_inst_executed.ratio,l1tex__t_bytes_pipe_lsu_mem_local_op_ld.sum,l1tex__t_bytes_pipe_lsu_mem_local_op_st.sum,sm__warps_active.avg.pct_of_peak_sustained_active,launch__registers_per_thread,gpu__time_duration.sum,smsp__average_warp_latency_issue_stalled_lg_throttle.ratio,smsp__average_warps_issue_stalled_long_scoreboard_per_issue_active.ratio,smsp__average_warps_issue_stalled_branch_resolving_per_issue_active.ratio,smsp__average_warps_issue_stalled_no_instruction_per_issue_active.ratio
for c in "to rest, reach" "to rest, reach + map"; do
  timeout 120 /usr/local/cuda/bin/ncu -k regex:ricochet_kernel -c 1 --metrics $M python3 -m bench.profile_map --device cuda:0 --n 2e5 --case "$c" 2>&1 | grep -v "^==PROF==\|^Warp\|CUDA Toolkit\|Devices\|Kernel cache\|cuda:0\|\"cpu\"" | tail -22
done
