/* portal_finder.h: `portals: auto`: the portals of a light inside a shade,
   found from the geometry when the scene is built, so that every path of
   every run sees the same portals.

   The construction is complete by design. P is the convex hull of the
   shapes around the light (the shapes that rays from the light meet first,
   nearest first, until their hull holds the light strictly inside, then
   without any of them whose removal leaves less open area; the same with
   the shapes' connected pieces in place of the shapes, when a shape met
   has several, and the tighter of the two is kept); every part of
   P's boundary that no opaque surface lying in it covers becomes a
   portal, except whole facets that a layer of surface just under them
   provably closes (facet_layer_covers, geometry/facet_cover.h). A segment from a point of the light (inside P) to a point
   outside P crosses P's boundary exactly once; if nothing blocks it, it
   crosses where no surface lies, which is on a portal. That holds for any
   convex P that strictly contains the light: the choice of shapes only
   decides how tight the portals are. Points inside P are inside the
   light's shade for the strategies (strategy.h), which sample the light
   itself there.

   Single-threaded, with fixed seeds: the same scene gives the same portals
   bit for bit whatever render.threads. */
#ifndef PORTAL_FINDER_H
#define PORTAL_FINDER_H

#include <stdbool.h>

#include "base/error.h"
#include "scene/scene.h"

struct config; /* config.h */

/* Rays cast from each light to find the shapes around it. */
#define PORTAL_FINDER_RAYS 8192
/* A shape whose bounding box is larger than this fraction of the scene's
   is a room, a floor or a wall, never a shade: it is not considered. */
#define PORTAL_FINDER_MAX_SHAPE_FRACTION 0.5
/* An enclosure whose uncovered boundary is more than this fraction of its
   area is no shade: its light gets no portals. */
#define PORTAL_FINDER_MAX_OPEN_FRACTION 0.75
/* More portals than this cost every shading point more than they save (a
   curved shell's hull leaves a sliver between each hull facet and the
   surface under it): the light gets none, with a warning. */
#define PORTAL_FINDER_MAX_PORTALS 64
/* Shapes beyond the first hull that holds the light tried for a tighter
   one (the nearby ones only). */
#define PORTAL_FINDER_MAX_EXTRA 16
/* The connected pieces of the shapes met (a lamp modelled as one mesh
   holds its shade, arm and base) are tried as candidates besides the
   whole shapes when they are at most this many. */
#define PORTAL_FINDER_MAX_PIECES 64
/* The seed of the finder's rays (a constant: the portals must not depend
   on render.seed, which a resumed or repeated run may change); the
   coverage counts of portal_report.h use the next one. */
#define PORTAL_FINDER_SEED 0x706f7274616c73ull

/* Finds the portals of every light of cfg with auto_portals and adds them
   to s (scene_add_portals), filling s->auto_portals. A light that nothing
   encloses gets no portal and a note; a light that touches or pierces the
   hull around it, or whose portals the antishadow rejects, gets no portal
   and a warning (report.warn): it is then sampled as `light` samples it,
   which is unbiased. Fails only on memory or an Embree error. */
bool portal_finder_run(struct scene *s, const struct config *cfg, struct error *err);

#endif
