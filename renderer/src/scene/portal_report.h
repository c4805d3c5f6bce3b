/* portal_report.h: what `portals: auto` (scene/portal_finder.h) found, as
   render --print-config writes it. */
#ifndef PORTAL_REPORT_H
#define PORTAL_REPORT_H

#include <stdbool.h>
#include <stdio.h>

#include "base/error.h"
#include "scene/scene.h"

struct config; /* config.h */

/* Writes what `portals: auto` found as YAML comments, for render
   --print-config: per light a summary line (portals, their area, the
   blocked fraction and the coverage bound from n_rays rays), then the
   found portals as ordinary `portals:` entries that a user can paste into
   a config in place of the auto entries. Nothing when no light asked for
   auto portals. */
bool portal_finder_write_summary(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                                 struct error *err);

/* The same as one JSON object, for render --print-config --format json:
   {"<light>": {"enclosed", "warning", "note", "n_portals", "area",
   "hull_area", "blocked_fraction", "bound", "n_rays", "n_escaped",
   "n_missed" (these five only when enclosed), "portals": [{"name",
   "light", "vertices"}...]}...} over the lights that asked for auto
   portals ({} when none did). */
bool portal_finder_write_json(const struct scene *s, const struct config *cfg, long n_rays, FILE *out,
                              struct error *err);

/* The rays of the coverage count that render --print-config makes per
   light with auto portals (fixed seed, single-threaded: the same numbers
   whatever render.threads). 2^17 keeps it well under a second on the
   shipped scenes; with every ray escaping the bound is 2.3e-5, so the
   1e-5 goal needs test_portal_finder's longer counts. */
#define PORTAL_FINDER_SUMMARY_RAYS 131072L

#endif
