/* exit_code.h: the exit statuses of `render`, chosen only by main.c and
   listed by `render --describe`. */
#ifndef EXIT_CODE_H
#define EXIT_CODE_H

/* Each value is also the index of its name in exit_code_names. */
enum exit_code { EXIT_DONE = 0, EXIT_RUNTIME = 1, EXIT_USAGE = 2, EXIT_INTERRUPTED = 3 };
#define EXIT_CODE_COUNT 4

/* "done", "runtime", "usage", "interrupted", indexed by enum exit_code. */
extern const char *const exit_code_names[EXIT_CODE_COUNT];

#endif
