/* main.c: command dispatch (being written by the coordinator). */
#include <stdio.h>
int main(void) { fprintf(stderr, "baker: under construction\n"); return 1; }
