/* merge.h: the `baker merge` command (merge_cmd.c): photon shards of one
 * frame (shard.h) added and finished into the frame's grids. argv[0] is
 * "merge"; returns the exit status (0 ok, 2 bad input, 1 runtime). */
#ifndef BAKER_MERGE_H
#define BAKER_MERGE_H

int merge_main(int argc, char **argv);

#endif
