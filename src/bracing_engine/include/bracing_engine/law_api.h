/* The engine's law and the controller's state check through a plain C ABI, for another extension module
 * (bracing_rcl's per-state path on rcl) that must call them without Python and without linking the engine:
 * bracing_engine.law_api(law) hands out a capsule (LAW_API_CAPSULE) holding a BracingLawApi. */
#ifndef BRACING_ENGINE_LAW_API_H
#define BRACING_ENGINE_LAW_API_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define BRACING_LAW_API_CAPSULE "bracing_engine.law_api"
#define BRACING_LAW_API_VERSION 1

/* What BracingLawApi.answer returns. */
enum BracingAnswerStatus {
  BRACING_ANSWERED = 0,        /* out holds the answer */
  BRACING_LAW_FAILED = 1,      /* the law raised ValueError/ArithmeticError's like (message in error) */
  BRACING_LAW_INTERNAL = 2,    /* any other exception: error holds "<Python type name>: <message>" */
  BRACING_NOT_FINITE = 3       /* an output is not finite (nothing to send) */
};

/* One answer; the caller owns the buffers: command n, hand 3 each, desired_normal_force b, braces 3 b each
 * (row-major b x 3). */
typedef struct {
  double* command;
  double* hand_desired;
  double* hand_actual;
  double* desired_normal_force;
  double* brace_desired;
  double* brace_actual;
  double compute_time_s; /* [s] wall, the law's update */
  int damped;            /* B near-singular: a damped inverse was used */
} BracingLawAnswer;

typedef struct {
  int version;
  void* law; /* the engine's Law (kept alive by the capsule's owner) */
  int joints, braces;
  /* The state check every answered joint state passes (after its names are matched): 0, or 1 with the
   * refusal's kind and message (NUL-terminated, cut to size). */
  int (*state_refusal)(int64_t stamp_ns, const double* q, const double* dq, int n, char* kind, char* message,
                       size_t size);
  /* The law's answer to (q, dq) stamped stamp_ns (t = stamp_seconds(stamp_ns)), api this BracingLawApi: a
   * BracingAnswerStatus. */
  int (*answer)(const void* api, int64_t stamp_ns, const double* q, const double* dq, BracingLawAnswer* out,
                char* error, size_t size);
} BracingLawApi;

#ifdef __cplusplus
}
#endif

#endif
