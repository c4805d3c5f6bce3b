#include "config/expr.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Recursive descent over
     sum     := product (("+" | "-") product)*
     product := unary (("*" | "/") unary)*
     unary   := ("-" | "+") unary | power
     power   := primary ("^" unary)?
     primary := number | name | name "(" sum ("," sum)* ")" | "(" sum ")"
   so that -2^2 = -(2^2) and 2^3^2 = 2^(3^2), as in mathematics. Nesting is
   bounded so hostile input cannot exhaust the stack. */
#define EXPR_DEPTH_MAX 64
#define EXPR_ARGS_MAX  16
#define EXPR_NAME_MAX  64

enum func { FUNC_MIN, FUNC_MAX, FUNC_ABS, FUNC_SQRT, FUNC_SIN, FUNC_COS, FUNC_TAN };

static const struct {
    const char *name;
    enum func func;
    int min_args, max_args;
} functions[] = {
    { "min", FUNC_MIN, 2, EXPR_ARGS_MAX },
    { "max", FUNC_MAX, 2, EXPR_ARGS_MAX },
    { "abs", FUNC_ABS, 1, 1 },
    { "sqrt", FUNC_SQRT, 1, 1 },
    { "sin", FUNC_SIN, 1, 1 },
    { "cos", FUNC_COS, 1, 1 },
    { "tan", FUNC_TAN, 1, 1 },
};
#define N_FUNCTIONS ((int)(sizeof functions / sizeof functions[0]))

struct parser {
    const char *p;
    const struct expr_var *vars;
    int n_vars;
    int depth;
    struct error *err;
};

static void skip_space(struct parser *ps)
{
    while (*ps->p == ' ' || *ps->p == '\t') ++ps->p;
}

/* Names the offending spot: the rest of the text, shortened. */
static bool fail_unexpected(struct parser *ps, const char *expected)
{
    if (*ps->p == '\0') return error_set(ps->err, "unexpected end of expression (expected %s)", expected);
    return error_set(ps->err, "syntax error at \"%.20s\" (expected %s)", ps->p, expected);
}

/* Every intermediate value must be finite: an infinity that a later division
   would turn back into 0 is still a mistake in the config. */
static bool check_finite(struct parser *ps, double v, const char *what)
{
    if (isfinite(v)) return true;
    return error_set(ps->err, "%s is not finite (%g)", what, v);
}

static bool parse_sum(struct parser *ps, double *out);
static bool parse_unary(struct parser *ps, double *out);

static bool parse_number(struct parser *ps, double *out)
{
    /* Validate the decimal form ourselves: strtod alone would also accept
       "inf", "nan" and hexadecimal. */
    const char *s = ps->p, *q = s;
    bool digits = false;
    while (isdigit((unsigned char)*q)) ++q, digits = true;
    if (*q == '.') {
        ++q;
        while (isdigit((unsigned char)*q)) ++q, digits = true;
    }
    if (!digits) return fail_unexpected(ps, "a number");
    if (*q == 'e' || *q == 'E') {
        const char *e = q + 1;
        if (*e == '+' || *e == '-') ++e;
        if (!isdigit((unsigned char)*e)) {
            ps->p = q;
            return fail_unexpected(ps, "an exponent");
        }
        while (isdigit((unsigned char)*e)) ++e;
        q = e;
    }
    char buf[64];
    size_t n = (size_t)(q - s);
    if (n >= sizeof buf) return error_set(ps->err, "number \"%.20s...\" is too long", s);
    memcpy(buf, s, n);
    buf[n] = '\0';
    *out = strtod(buf, NULL);
    ps->p = q;
    return check_finite(ps, *out, "number");
}

static bool apply_function(struct parser *ps, int f, const double *args, int n, double *out)
{
    double v = args[0];
    switch (functions[f].func) {
    case FUNC_MIN:
        for (int i = 1; i < n; ++i) v = args[i] < v ? args[i] : v;
        break;
    case FUNC_MAX:
        for (int i = 1; i < n; ++i) v = args[i] > v ? args[i] : v;
        break;
    case FUNC_ABS:
        v = fabs(v);
        break;
    case FUNC_SQRT:
        if (v < 0.0) return error_set(ps->err, "sqrt of a negative number (%g)", v);
        v = sqrt(v);
        break;
    case FUNC_SIN:
        v = sin(v);
        break;
    case FUNC_COS:
        v = cos(v);
        break;
    case FUNC_TAN:
        v = tan(v);
        break;
    }
    *out = v;
    return check_finite(ps, v, functions[f].name);
}

static bool parse_call(struct parser *ps, int f, double *out)
{
    double args[EXPR_ARGS_MAX];
    int n = 0;
    ++ps->p; /* "(" */
    for (;;) {
        if (n == EXPR_ARGS_MAX)
            return error_set(ps->err, "too many arguments to %s (expected at most %d)", functions[f].name,
                             EXPR_ARGS_MAX);
        if (!parse_sum(ps, &args[n++])) return false;
        skip_space(ps);
        if (*ps->p == ',') {
            ++ps->p;
            continue;
        }
        if (*ps->p == ')') break;
        return fail_unexpected(ps, "\",\" or \")\"");
    }
    ++ps->p;
    if (n < functions[f].min_args || n > functions[f].max_args) {
        if (functions[f].min_args == functions[f].max_args)
            return error_set(ps->err, "%s takes %d argument%s, got %d", functions[f].name, functions[f].min_args,
                             functions[f].min_args == 1 ? "" : "s", n);
        return error_set(ps->err, "%s takes at least %d arguments, got %d", functions[f].name, functions[f].min_args,
                         n);
    }
    return apply_function(ps, f, args, n, out);
}

/* "(expected one of: a, b, pi)" listing the variables in scope. */
static bool fail_unknown_name(struct parser *ps, const char *name)
{
    char list[ERROR_MESSAGE_MAX / 2] = "";
    size_t used = 0;
    for (int i = 0; i < ps->n_vars && used < sizeof list; ++i) {
        int k = snprintf(list + used, sizeof list - used, "%s, ", ps->vars[i].name);
        if (k < 0) break;
        used += (size_t)k;
    }
    return error_set(ps->err, "unknown name \"%s\" (expected one of: %spi)", name, list);
}

static bool parse_name(struct parser *ps, double *out)
{
    const char *s = ps->p;
    while (isalnum((unsigned char)*ps->p) || *ps->p == '_') ++ps->p;
    size_t n = (size_t)(ps->p - s);
    char name[EXPR_NAME_MAX];
    if (n >= sizeof name) return error_set(ps->err, "name \"%.20s...\" is too long", s);
    memcpy(name, s, n);
    name[n] = '\0';

    skip_space(ps);
    for (int f = 0; f < N_FUNCTIONS; ++f)
        if (strcmp(name, functions[f].name) == 0) {
            if (*ps->p != '(') return fail_unexpected(ps, "\"(\" after a function name");
            return parse_call(ps, f, out);
        }
    if (*ps->p == '(')
        return error_set(ps->err, "unknown function \"%s\" (expected one of: min, max, abs, sqrt, sin, cos, tan)",
                         name);
    if (strcmp(name, "pi") == 0) {
        *out = M_PI;
        return true;
    }
    /* Last definition wins, like a later --set of the same param. */
    for (int i = ps->n_vars - 1; i >= 0; --i)
        if (strcmp(name, ps->vars[i].name) == 0) {
            *out = ps->vars[i].value;
            return true;
        }
    return fail_unknown_name(ps, name);
}

static bool parse_primary(struct parser *ps, double *out)
{
    skip_space(ps);
    char c = *ps->p;
    if (c == '(') {
        ++ps->p;
        if (!parse_sum(ps, out)) return false;
        skip_space(ps);
        if (*ps->p != ')') return fail_unexpected(ps, "\")\"");
        ++ps->p;
        return true;
    }
    if (isdigit((unsigned char)c) || c == '.') return parse_number(ps, out);
    if (isalpha((unsigned char)c) || c == '_') return parse_name(ps, out);
    return fail_unexpected(ps, "a number, a name or \"(\"");
}

static bool parse_power(struct parser *ps, double *out)
{
    double base, exponent;
    if (!parse_primary(ps, &base)) return false;
    skip_space(ps);
    if (*ps->p != '^') {
        *out = base;
        return true;
    }
    ++ps->p;
    if (!parse_unary(ps, &exponent)) return false;
    *out = pow(base, exponent);
    return check_finite(ps, *out, "power");
}

/* Counts depth here: unary signs and right-associative powers both recurse
   through this function. */
static bool parse_unary(struct parser *ps, double *out)
{
    if (++ps->depth > EXPR_DEPTH_MAX) return error_set(ps->err, "expression nested too deeply");
    skip_space(ps);
    char c = *ps->p;
    bool ok;
    if (c == '-' || c == '+') {
        ++ps->p;
        ok = parse_unary(ps, out);
        if (ok && c == '-') *out = -*out;
    } else {
        ok = parse_power(ps, out);
    }
    --ps->depth;
    return ok;
}

static bool parse_product(struct parser *ps, double *out)
{
    if (!parse_unary(ps, out)) return false;
    for (;;) {
        skip_space(ps);
        char op = *ps->p;
        if (op != '*' && op != '/') return true;
        ++ps->p;
        double rhs;
        if (!parse_unary(ps, &rhs)) return false;
        if (op == '/' && rhs == 0.0) return error_set(ps->err, "division by zero");
        *out = op == '*' ? *out * rhs : *out / rhs;
        if (!check_finite(ps, *out, op == '*' ? "product" : "quotient")) return false;
    }
}

static bool parse_sum(struct parser *ps, double *out)
{
    if (++ps->depth > EXPR_DEPTH_MAX) return error_set(ps->err, "expression nested too deeply");
    bool ok = parse_product(ps, out);
    while (ok) {
        skip_space(ps);
        char op = *ps->p;
        if (op != '+' && op != '-') break;
        ++ps->p;
        double rhs;
        ok = parse_product(ps, &rhs);
        if (ok) {
            *out = op == '+' ? *out + rhs : *out - rhs;
            ok = check_finite(ps, *out, op == '+' ? "sum" : "difference");
        }
    }
    --ps->depth;
    return ok;
}

bool expr_eval(const char *text, const struct expr_var *vars, int n_vars, double *out, struct error *err)
{
    struct parser ps = { text, vars, n_vars, 0, err };
    double v;
    if (!parse_sum(&ps, &v)) return false;
    skip_space(&ps);
    if (*ps.p != '\0') return fail_unexpected(&ps, "an operator or the end");
    *out = v;
    return true;
}

bool expr_is_identifier(const char *name)
{
    if (!(isalpha((unsigned char)name[0]) || name[0] == '_')) return false;
    for (const char *p = name; *p; ++p)
        if (!(isalnum((unsigned char)*p) || *p == '_')) return false;
    return strlen(name) < EXPR_NAME_MAX;
}

bool expr_is_reserved(const char *name)
{
    if (strcmp(name, "pi") == 0) return true;
    for (int f = 0; f < N_FUNCTIONS; ++f)
        if (strcmp(name, functions[f].name) == 0) return true;
    return false;
}
