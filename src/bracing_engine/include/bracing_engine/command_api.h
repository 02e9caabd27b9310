/* The motor command's value rule through a plain C ABI, for another extension module (bracing_rcl's command path
 * on rcl) that must call it without Python and without linking the engine; the simulator's Python path calls the
 * same function through the engine's binding (bracing_engine.check_command): one implementation of the rule.
 * bracing_engine.command_api() hands out a capsule (BRACING_COMMAND_API_CAPSULE) holding a BracingCommandApi. */
#ifndef BRACING_ENGINE_COMMAND_API_H
#define BRACING_ENGINE_COMMAND_API_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define BRACING_COMMAND_API_CAPSULE "bracing_engine.command_api"
#define BRACING_COMMAND_API_VERSION 1

typedef struct {
  int version;
  /* A command's n values (in the joints' order) under the rule: every value finite, then each saturated to its
   * joint's limit (limit[k] > 0; any other limit: none), as np.clip(values, -limit, limit) does. Returns how
   * many values are not finite, their indices (ascending) the first of non_finite (room for n), and writes
   * nothing else; or 0, with out the values saturated and *saturated 1 if any value was over its limit. */
  size_t (*check_command)(const double* values, const double* limit, size_t n, double* out, int* saturated,
                          size_t* non_finite);
} BracingCommandApi;

#ifdef __cplusplus
}
#endif

#endif
