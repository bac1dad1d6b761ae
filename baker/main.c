/* main.c: command dispatch (the full version lands with the viewing pass). */
#include "bake.h"
int main(int argc, char **argv) { return argc > 1 ? bake_main(argc - 1, argv + 1) : 2; }
