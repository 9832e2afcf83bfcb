/* SPDX-License-Identifier: MIT */
/* afmtwin_cmds.h -- the subcommands of the `afmtwin` tool, one source file each. */
#ifndef AFMTWIN_CMDS_H
#define AFMTWIN_CMDS_H

/* Each takes the arguments after the subcommand name (argv[0] is the subcommand) and
 * returns the process exit code: 0 ok, 1 failure, 2 bad usage or bad input. */
int afm_cmd_modes(int argc, char **argv);
int afm_cmd_sweep(int argc, char **argv);
int afm_cmd_approach(int argc, char **argv);
int afm_cmd_force_curve(int argc, char **argv);
int afm_cmd_plot(int argc, char **argv);
int afm_cmd_curve(int argc, char **argv);
int afm_cmd_scan(int argc, char **argv);
int afm_cmd_bench(int argc, char **argv);
int afm_cmd_thermal(int argc, char **argv);
int afm_cmd_send(int argc, char **argv);
int afm_cmd_listen(int argc, char **argv);
int afm_cmd_replay(int argc, char **argv);
int afm_cmd_bench_daemon(int argc, char **argv);
int afm_cmd_bench_states(int argc, char **argv);
int afm_cmd_bench_scheme(int argc, char **argv);
int afm_cmd_bench_fm(int argc, char **argv);
int afm_cmd_lockstep(int argc, char **argv);
int afm_cmd_soak(int argc, char **argv);
int afm_cmd_can_send(int argc, char **argv);
int afm_cmd_flood(int argc, char **argv);
int afm_cmd_continue(int argc, char **argv);
int afm_cmd_map(int argc, char **argv);
int afm_cmd_plot_map(int argc, char **argv);
int afm_cmd_plan(int argc, char **argv);

#endif
