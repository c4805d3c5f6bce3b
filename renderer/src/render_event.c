#include "render_event.h"

const char *const render_event_names[RENDER_EVENT_COUNT] = {
    [RENDER_EVENT_START] = "start",
    [RENDER_EVENT_SNAPSHOT] = "snapshot",
    [RENDER_EVENT_FINAL] = "final",
};
