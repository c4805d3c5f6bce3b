#include "base/json_write.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Length of the valid UTF-8 sequence at s (at most n bytes) and its code
   point; 0 when the bytes there are not valid UTF-8 (a stray continuation
   byte, a truncated or overlong sequence, a surrogate, beyond U+10FFFF). */
static size_t utf8_decode(const unsigned char *s, size_t n, unsigned long *cp)
{
    size_t len = s[0] < 0x80             ? 1
                 : (s[0] & 0xE0) == 0xC0 ? 2
                 : (s[0] & 0xF0) == 0xE0 ? 3
                 : (s[0] & 0xF8) == 0xF0 ? 4
                                         : 0;
    if (len == 0 || len > n) return 0;
    unsigned long c = len == 1 ? s[0] : s[0] & (0x7Fu >> len);
    for (size_t i = 1; i < len; ++i) {
        if ((s[i] & 0xC0) != 0x80) return 0;
        c = (c << 6) | (s[i] & 0x3F);
    }
    static const unsigned long min_of_len[5] = { 0, 0, 0x80, 0x800, 0x10000 };
    if (c < min_of_len[len] || c > 0x10FFFF || (c >= 0xD800 && c <= 0xDFFF)) return 0;
    *cp = c;
    return len;
}

/* The body of a JSON string, without the quotes. */
static void write_escaped(FILE *out, const char *s, size_t n)
{
    const unsigned char *p = (const unsigned char *)s;
    for (size_t i = 0; i < n;) {
        unsigned char b = p[i];
        if (b == '"' || b == '\\') {
            fprintf(out, "\\%c", b);
            ++i;
        } else if (b == '\n') {
            fputs("\\n", out);
            ++i;
        } else if (b == '\t') {
            fputs("\\t", out);
            ++i;
        } else if (b < 0x20 || b == 0x7F) {
            fprintf(out, "\\u%04x", b);
            ++i;
        } else if (b < 0x80) {
            fputc(b, out);
            ++i;
        } else {
            unsigned long c;
            size_t len = utf8_decode(p + i, n - i, &c);
            if (len == 0) {
                fputs("\\ufffd", out);
                ++i;
                continue;
            }
            if (c > 0xFFFF) {
                c -= 0x10000;
                fprintf(out, "\\u%04lx\\u%04lx", 0xD800 + (c >> 10), 0xDC00 + (c & 0x3FF));
            } else {
                fprintf(out, "\\u%04lx", c);
            }
            i += len;
        }
    }
}

void json_write_string_n(FILE *out, const char *s, size_t n)
{
    fputc('"', out);
    write_escaped(out, s, n);
    fputc('"', out);
}

void json_write_string(FILE *out, const char *s)
{
    json_write_string_n(out, s, strlen(s));
}

void json_write_number(FILE *out, double v)
{
    if (!isfinite(v)) {
        fputs("null", out);
        return;
    }
    char buf[32];
    for (int digits = 15; digits <= 17; ++digits) {
        snprintf(buf, sizeof buf, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) break;
    }
    fputs(buf, out);
}

void json_write_names(FILE *out, const char *prefix, const char *const *names, int n)
{
    fputc('[', out);
    for (int i = 0; i < n; ++i) {
        if (i) fputc(',', out);
        fputc('"', out);
        if (prefix) write_escaped(out, prefix, strlen(prefix));
        write_escaped(out, names[i], strlen(names[i]));
        fputc('"', out);
    }
    fputc(']', out);
}
