/* json_write.h: writing JSON values to a stream: strings (escaped, ASCII
   output), numbers that read back to the same double, arrays of names.
   Errors are the stream's: callers check ferror() once at the end.
   It knows no event or config: describe.c, print_config.c and
   render_events.c decide what to write. */
#ifndef JSON_WRITE_H
#define JSON_WRITE_H

#include <stddef.h>
#include <stdio.h>

/* The n bytes of s (UTF-8, may hold NUL bytes) as a JSON string. Quote,
   backslash and controls are escaped, every non-ASCII character becomes
   \uXXXX (a surrogate pair above U+FFFF), so the output is ASCII whatever
   the reader's encoding; a byte that is not part of valid UTF-8 becomes
   \ufffd. */
void json_write_string_n(FILE *out, const char *s, size_t n);
/* Same for a NUL-terminated string. */
void json_write_string(FILE *out, const char *s);
/* The shortest of %.15g, %.16g, %.17g that reads back to v (so 0.6 is
   written 0.6); JSON has no infinity or NaN, so those are written null. */
void json_write_number(FILE *out, double v);
/* ["names[0]", ..., "names[n - 1]"], each prefixed with `prefix` (NULL or
   "" for none). */
void json_write_names(FILE *out, const char *prefix, const char *const *names, int n);

#endif
