/* libFuzzer target: the config loader must reject or accept any bytes
   without crashing, leaking or invoking undefined behaviour; what it
   accepts must round-trip through its effective YAML. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "config/config.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct config cfg;
    struct error err;
    if (!config_load_string((const char *)data, size, "fuzz.yaml", NULL, 0, &cfg, &err)) return 0;
    struct config again;
    if (!config_load_string(cfg.effective_yaml, strlen(cfg.effective_yaml), "effective.yaml", NULL, 0, &again, &err))
        abort(); /* an accepted config must load back */
    if (again.hash != cfg.hash) abort();
    config_free(&again);
    config_free(&cfg);
    return 0;
}
