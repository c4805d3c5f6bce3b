/* expr.h: the small arithmetic language configs may use wherever a number is
   expected ("=max(s_L, s_P) / 2 + 0.05"): + - * / ^ (right-associative),
   unary minus, parentheses, min, max (2+ arguments), abs, sqrt, sin, cos, tan
   (radians), the constant pi and named variables (the config's params).
   It evaluates text only: it knows no config keys (the config module
   decides where expressions may appear). */
#ifndef EXPR_H
#define EXPR_H

#include <stdbool.h>

#include "base/error.h"

struct expr_var {
    const char *name;
    double value;
};

/* Evaluates `text` (without the leading "=") with the given variables. Every
   intermediate result must be finite. On failure err holds the reason without
   a location (e.g. `unknown name "s_l" (expected one of: s_L, pi)`); the
   caller adds the location and the text. */
bool expr_eval(const char *text, const struct expr_var *vars, int n_vars, double *out, struct error *err);

/* True for [A-Za-z_][A-Za-z0-9_]*: the names expressions can refer to. */
bool expr_is_identifier(const char *name);
/* True for the built-in names (pi and the functions) that variables may not use. */
bool expr_is_reserved(const char *name);

#endif
