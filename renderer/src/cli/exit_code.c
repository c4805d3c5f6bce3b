#include "cli/exit_code.h"

const char *const exit_code_names[EXIT_CODE_COUNT] = {
    [EXIT_DONE] = "done",
    [EXIT_RUNTIME] = "runtime",
    [EXIT_USAGE] = "usage",
    [EXIT_INTERRUPTED] = "interrupted",
};
