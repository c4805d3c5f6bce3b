/* json_util.h: a strict JSON reader for tests (RFC 8259: one value, no
   trailing commas, no raw control characters in strings, valid escapes and
   surrogate pairs, no duplicate keys), so that the renderer's JSON output
   is checked without Python. Strings are decoded to UTF-8. */
#ifndef JSON_UTIL_H
#define JSON_UTIL_H

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum jtype { J_NULL, J_BOOL, J_NUMBER, J_STRING, J_ARRAY, J_OBJECT };

struct jval {
    enum jtype type;
    bool boolean;
    double number;
    char *text;    /* J_NUMBER: the number as written; J_STRING: decoded, NUL-terminated */
    size_t length; /* of text */
    int n;         /* J_ARRAY, J_OBJECT: items */
    char **keys;   /* J_OBJECT: decoded keys, in order */
    struct jval *items;
};

struct jparser {
    const char *s;
    size_t pos;
    char why[200];
    int depth;
};

static inline bool jfail(struct jparser *p, const char *what)
{
    if (!p->why[0]) snprintf(p->why, sizeof p->why, "offset %zu: %s", p->pos, what);
    return false;
}

static inline void jskip(struct jparser *p)
{
    while (p->s[p->pos] == ' ' || p->s[p->pos] == '\t' || p->s[p->pos] == '\n' || p->s[p->pos] == '\r') ++p->pos;
}

static inline void jfree(struct jval *v)
{
    free(v->text);
    for (int i = 0; i < v->n; ++i) {
        if (v->keys) free(v->keys[i]);
        jfree(&v->items[i]);
    }
    free(v->keys);
    free(v->items);
    memset(v, 0, sizeof *v);
}

static inline int jhex4(const char *s)
{
    int v = 0;
    for (int i = 0; i < 4; ++i) {
        char c = s[i];
        int d = c >= '0' && c <= '9'   ? c - '0'
                : c >= 'a' && c <= 'f' ? c - 'a' + 10
                : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                       : -1;
        if (d < 0) return -1;
        v = v * 16 + d;
    }
    return v;
}

static inline void jput_utf8(char *out, size_t *n, unsigned long c)
{
    if (c < 0x80) out[(*n)++] = (char)c;
    else if (c < 0x800) {
        out[(*n)++] = (char)(0xC0 | (c >> 6));
        out[(*n)++] = (char)(0x80 | (c & 0x3F));
    } else if (c < 0x10000) {
        out[(*n)++] = (char)(0xE0 | (c >> 12));
        out[(*n)++] = (char)(0x80 | ((c >> 6) & 0x3F));
        out[(*n)++] = (char)(0x80 | (c & 0x3F));
    } else {
        out[(*n)++] = (char)(0xF0 | (c >> 18));
        out[(*n)++] = (char)(0x80 | ((c >> 12) & 0x3F));
        out[(*n)++] = (char)(0x80 | ((c >> 6) & 0x3F));
        out[(*n)++] = (char)(0x80 | (c & 0x3F));
    }
}

/* At the opening quote; decodes into a new string. */
static inline bool jstring(struct jparser *p, char **out, size_t *len)
{
    ++p->pos;
    size_t start = p->pos, cap = 0;
    while (p->s[start + cap] && p->s[start + cap] != '"')
        cap += p->s[start + cap] == '\\' && p->s[start + cap + 1] ? 2 : 1;
    char *buf = malloc(cap * 2 + 8); /* \uXXXX never grows, raw bytes are copied */
    if (!buf) return jfail(p, "out of memory");
    size_t n = 0;
    for (;;) {
        unsigned char c = (unsigned char)p->s[p->pos];
        if (c == '\0') {
            free(buf);
            return jfail(p, "unterminated string");
        }
        if (c == '"') break;
        if (c < 0x20) {
            free(buf);
            return jfail(p, "raw control character in a string");
        }
        if (c != '\\') {
            buf[n++] = (char)c;
            ++p->pos;
            continue;
        }
        char e = p->s[p->pos + 1];
        const char *simple = strchr("\"\\/bfnrt", e);
        if (e && simple) {
            static const char map[] = "\"\\/\b\f\n\r\t";
            buf[n++] = map[simple - "\"\\/bfnrt"];
            p->pos += 2;
            continue;
        }
        if (e != 'u' || jhex4(p->s + p->pos + 2) < 0) {
            free(buf);
            return jfail(p, "bad escape");
        }
        unsigned long cp = (unsigned long)jhex4(p->s + p->pos + 2);
        p->pos += 6;
        if (cp >= 0xDC00 && cp <= 0xDFFF) {
            free(buf);
            return jfail(p, "lone low surrogate");
        }
        if (cp >= 0xD800 && cp <= 0xDBFF) {
            int lo = p->s[p->pos] == '\\' && p->s[p->pos + 1] == 'u' ? jhex4(p->s + p->pos + 2) : -1;
            if (lo < 0xDC00 || lo > 0xDFFF) {
                free(buf);
                return jfail(p, "lone high surrogate");
            }
            cp = 0x10000 + ((cp - 0xD800) << 10) + ((unsigned long)lo - 0xDC00);
            p->pos += 6;
        }
        jput_utf8(buf, &n, cp);
    }
    ++p->pos;
    buf[n] = '\0';
    *out = buf;
    *len = n;
    return true;
}

static inline bool jvalue(struct jparser *p, struct jval *v);

static inline bool jnumber(struct jparser *p, struct jval *v)
{
    size_t start = p->pos;
    const char *s = p->s;
    if (s[p->pos] == '-') ++p->pos;
    if (s[p->pos] == '0') ++p->pos;
    else if (s[p->pos] >= '1' && s[p->pos] <= '9')
        while (s[p->pos] >= '0' && s[p->pos] <= '9') ++p->pos;
    else return jfail(p, "bad number");
    if (s[p->pos] == '.') {
        ++p->pos;
        if (!(s[p->pos] >= '0' && s[p->pos] <= '9')) return jfail(p, "bad fraction");
        while (s[p->pos] >= '0' && s[p->pos] <= '9') ++p->pos;
    }
    if (s[p->pos] == 'e' || s[p->pos] == 'E') {
        ++p->pos;
        if (s[p->pos] == '+' || s[p->pos] == '-') ++p->pos;
        if (!(s[p->pos] >= '0' && s[p->pos] <= '9')) return jfail(p, "bad exponent");
        while (s[p->pos] >= '0' && s[p->pos] <= '9') ++p->pos;
    }
    v->type = J_NUMBER;
    v->length = p->pos - start;
    v->text = malloc(v->length + 1);
    if (!v->text) return jfail(p, "out of memory");
    memcpy(v->text, s + start, v->length);
    v->text[v->length] = '\0';
    v->number = strtod(v->text, NULL);
    return true;
}

static inline bool jpush(struct jparser *p, struct jval *v, int *cap)
{
    if (v->n < *cap) return true;
    *cap = *cap ? 2 * *cap : 8;
    struct jval *items = realloc(v->items, (size_t)*cap * sizeof *items);
    if (!items) return jfail(p, "out of memory");
    v->items = items;
    if (v->type == J_OBJECT) {
        char **keys = realloc(v->keys, (size_t)*cap * sizeof *keys);
        if (!keys) return jfail(p, "out of memory");
        v->keys = keys;
    }
    return true;
}

static inline bool jcontainer(struct jparser *p, struct jval *v, bool object)
{
    char close = object ? '}' : ']';
    v->type = object ? J_OBJECT : J_ARRAY;
    int cap = 0;
    ++p->pos;
    jskip(p);
    if (p->s[p->pos] == close) {
        ++p->pos;
        return true;
    }
    for (;;) {
        if (!jpush(p, v, &cap)) return false;
        char *k = NULL;
        size_t klen = 0;
        if (object) {
            jskip(p);
            if (p->s[p->pos] != '"') return jfail(p, "expected a key");
            if (!jstring(p, &k, &klen)) return false;
            for (int i = 0; i < v->n; ++i)
                if (!strcmp(v->keys[i], k)) {
                    free(k);
                    return jfail(p, "duplicate key");
                }
            jskip(p);
            if (p->s[p->pos] != ':') {
                free(k);
                return jfail(p, "expected ':'");
            }
            ++p->pos;
            v->keys[v->n] = k;
        }
        memset(&v->items[v->n], 0, sizeof v->items[v->n]);
        ++v->n; /* counted before parsing, so that jfree frees what was made */
        if (!jvalue(p, &v->items[v->n - 1])) return false;
        jskip(p);
        if (p->s[p->pos] == ',') {
            ++p->pos;
            continue;
        }
        if (p->s[p->pos] == close) {
            ++p->pos;
            return true;
        }
        return jfail(p, object ? "expected ',' or '}'" : "expected ',' or ']'");
    }
}

static inline bool jvalue(struct jparser *p, struct jval *v)
{
    if (++p->depth > 200) return jfail(p, "nested too deeply");
    jskip(p);
    const char *s = p->s + p->pos;
    bool ok;
    if (*s == '{' || *s == '[') ok = jcontainer(p, v, *s == '{');
    else if (*s == '"') {
        v->type = J_STRING;
        ok = jstring(p, &v->text, &v->length);
    } else if (!strncmp(s, "true", 4) || !strncmp(s, "false", 5)) {
        v->type = J_BOOL;
        v->boolean = *s == 't';
        p->pos += v->boolean ? 4 : 5;
        ok = true;
    } else if (!strncmp(s, "null", 4)) {
        v->type = J_NULL;
        p->pos += 4;
        ok = true;
    } else ok = jnumber(p, v);
    --p->depth;
    return ok;
}

/* Parses all of text: one value, then only whitespace. On failure *v is
   zeroed and why (if not NULL, at least 200 bytes) says where. */
static inline bool json_parse(const char *text, struct jval *v, char *why)
{
    struct jparser p = { text, 0, { 0 }, 0 };
    memset(v, 0, sizeof *v);
    bool ok = jvalue(&p, v);
    jskip(&p);
    if (ok && text[p.pos]) ok = jfail(&p, "text after the value");
    if (!ok) jfree(v);
    if (why) snprintf(why, 200, "%s", p.why);
    return ok;
}

/* The value of key in an object, NULL when absent or v is not an object. */
static inline const struct jval *json_get(const struct jval *v, const char *key)
{
    if (!v || v->type != J_OBJECT) return NULL;
    for (int i = 0; i < v->n; ++i)
        if (!strcmp(v->keys[i], key)) return &v->items[i];
    return NULL;
}

/* True when v is an array of exactly the strings names[0..n-1], in order. */
static inline bool json_is_names(const struct jval *v, const char *prefix, const char *const *names, int n)
{
    if (!v || v->type != J_ARRAY || v->n != n) return false;
    size_t pl = prefix ? strlen(prefix) : 0;
    for (int i = 0; i < n; ++i) {
        const struct jval *it = &v->items[i];
        if (it->type != J_STRING || it->length != pl + strlen(names[i]) || (pl && memcmp(it->text, prefix, pl)) ||
            strcmp(it->text + pl, names[i]))
            return false;
    }
    return true;
}

#endif
