/* describe.h: `render --describe`: the renderer's contract as one JSON
   object (names of strategies, integrators, materials..., EXR channels and
   attributes, snapshot keys, exit codes, JSON events), each list read from
   the table the code itself uses, so that the harness asks instead of
   keeping copies.
   It restates no name: every list is the owning module's own table. */
#ifndef DESCRIBE_H
#define DESCRIBE_H

#include <stdio.h>

/* Writes the object and a newline to out. Write errors are the stream's
   (the caller checks ferror). */
void describe_write(FILE *out);

#endif
