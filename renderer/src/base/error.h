/* error.h: the error value every fallible function fills, and its formatter.
   A function that can fail returns bool and takes `struct error *err` last.
   It never prints: main.c alone reports errors and picks exit codes. */
#ifndef ERROR_H
#define ERROR_H

#include <stdbool.h>

#define ERROR_MESSAGE_MAX 1024

struct error {
    char message[ERROR_MESSAGE_MAX];
};

/* Formats the message into err (if err is not NULL) and returns false, so that
   reporting and returning are one expression: `return error_set(err, ...);` */
bool error_set(struct error *err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Same, prefixed with "file:line:column: " (line and column one-based). */
bool error_at(struct error *err, const char *file, int line, int column, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

#endif
