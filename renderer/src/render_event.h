/* render_event.h: the kinds of the JSON lines a render prints on stdout,
   the value of their "event" field: one "start", a "snapshot" per timed
   snapshot, one "final". render.c writes these names; `render --describe`
   lists them. */
#ifndef RENDER_EVENT_H
#define RENDER_EVENT_H

enum render_event { RENDER_EVENT_START, RENDER_EVENT_SNAPSHOT, RENDER_EVENT_FINAL };
#define RENDER_EVENT_COUNT 3

/* "start", "snapshot", "final", indexed by enum render_event. */
extern const char *const render_event_names[RENDER_EVENT_COUNT];

#endif
