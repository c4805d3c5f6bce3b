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
   blocked fraction and the coverage bound, see below), then the
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

/* The coverage count that render --print-config makes per light with auto
   portals: batches of PORTAL_FINDER_SUMMARY_RAYS rays (fixed seeds,
   single-threaded: the same numbers whatever render.threads) until
   PORTAL_FINDER_SUMMARY_ESCAPED rays escaped, so that the bound 3/N is at
   most 1e-5, the goal, or PORTAL_FINDER_SUMMARY_MAX_BATCHES batches (4.2M
   rays) were cast, which a light whose escaping fraction is below 7% does
   not reach: its bound is then larger, and printed as it is. The JSON form
   (what the harness reads for every point of an experiment, which does not
   use the bound) counts one batch, and says how many rays it cast. */
#define PORTAL_FINDER_SUMMARY_RAYS        131072L
#define PORTAL_FINDER_SUMMARY_ESCAPED     300000L
#define PORTAL_FINDER_SUMMARY_MAX_BATCHES 32

#endif
