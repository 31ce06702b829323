/* The C side of tests/capi.rs: opens a bank and a preset through the C API, samples and
 * fills them from two threads, walks every error path, and prints what it got for the
 * Rust test to compare with the library's own values.
 *
 * Usage: check BANK PRESET CORRUPT_BANK
 * Output lines (floats as the hex of their bits, coordinates as %.17g):
 *   abi N
 *   open SPEC channels C spacing S
 *   height SPEC X Y BITS
 *   fill SPEC X Y STEP W H STRIDE BITS...   (the W×H×C values, row by row)
 *   agree SPEC 1                            (both threads got the same bits)
 *   error CASE CODE MESSAGE
 * Exit status 0 unless a check made here failed (then a line "FAIL ..." says which). */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "surftile.h"

static int failures = 0;

#define CHECK(cond, ...)                                                                   \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            printf("FAIL line %d: ", __LINE__);                                            \
            printf(__VA_ARGS__);                                                           \
            printf("\n");                                                                  \
            failures++;                                                                    \
        }                                                                                  \
    } while (0)

static unsigned bits(float v) {
    unsigned u;
    memcpy(&u, &v, sizeof u);
    return u;
}

#define N_POINTS 6
static const double POINTS[N_POINTS][2] = {
    {0.0, 0.0},       {12.5, -7.0},          {-5.0e7, 3.25},
    {1.0e9, -42.25},  {-123456.75, 987.5},   {-5.0e7 + 0.125, -5.0e7 - 0.375},
};

/* Two fills: one with padded rows (stride > row), one contiguous, at x = -5e7. */
#define N_FILLS 2
static const double FILL_XY_STEP[N_FILLS][3] = {{-5.0e7 + 0.25, 1234.5, 0.75}, {-17.0, 3.0, 2.5}};
static const size_t FILL_WH[N_FILLS][2] = {{37, 23}, {16, 9}};
static const size_t FILL_PAD[N_FILLS] = {5, 0};
#define SENTINEL (-1234.5f)

struct job {
    const surftile_surface *s;
    size_t channels;
    float heights[N_POINTS];
    float *fills[N_FILLS];
    int status;
};

static void *run(void *arg) {
    struct job *j = arg;
    j->status = 0;
    for (int round = 0; round < 20; round++) {
        for (int i = 0; i < N_POINTS; i++)
            j->heights[i] = surftile_height(j->s, POINTS[i][0], POINTS[i][1]);
        for (int f = 0; f < N_FILLS; f++) {
            size_t w = FILL_WH[f][0], h = FILL_WH[f][1], stride = w * j->channels + FILL_PAD[f];
            for (size_t k = 0; k < h * stride; k++) j->fills[f][k] = SENTINEL;
            surftile_status st = surftile_fill(j->s, FILL_XY_STEP[f][0], FILL_XY_STEP[f][1],
                                               FILL_XY_STEP[f][2], w, h, j->fills[f], stride);
            if (st != SURFTILE_STATUS_OK) j->status = (int)st;
        }
    }
    return NULL;
}

static void sample(const char *spec, uint32_t seed) {
    surftile_surface *s = NULL;
    surftile_status st = surftile_open(spec, seed, &s);
    CHECK(st == SURFTILE_STATUS_OK && s != NULL, "open %s: %d %s", spec, (int)st,
          surftile_last_error());
    if (s == NULL) return;
    size_t c = surftile_channels(s);
    printf("open %s channels %zu spacing %.17g\n", spec, c, surftile_spacing_um(s));

    struct job jobs[2];
    pthread_t threads[2];
    for (int t = 0; t < 2; t++) {
        jobs[t].s = s;
        jobs[t].channels = c;
        for (int f = 0; f < N_FILLS; f++) {
            size_t stride = FILL_WH[f][0] * c + FILL_PAD[f];
            jobs[t].fills[f] = malloc(FILL_WH[f][1] * stride * sizeof(float));
        }
        CHECK(pthread_create(&threads[t], NULL, run, &jobs[t]) == 0, "pthread_create");
    }
    for (int t = 0; t < 2; t++) pthread_join(threads[t], NULL);

    int agree = 1;
    for (int t = 0; t < 2; t++) CHECK(jobs[t].status == 0, "fill status %d", jobs[t].status);
    for (int i = 0; i < N_POINTS; i++) {
        agree &= bits(jobs[0].heights[i]) == bits(jobs[1].heights[i]);
        printf("height %s %.17g %.17g %08x\n", spec, POINTS[i][0], POINTS[i][1],
               bits(jobs[0].heights[i]));
    }
    for (int f = 0; f < N_FILLS; f++) {
        size_t w = FILL_WH[f][0], h = FILL_WH[f][1], stride = w * c + FILL_PAD[f];
        agree &= memcmp(jobs[0].fills[f], jobs[1].fills[f], h * stride * sizeof(float)) == 0;
        printf("fill %s %.17g %.17g %.17g %zu %zu %zu", spec, FILL_XY_STEP[f][0],
               FILL_XY_STEP[f][1], FILL_XY_STEP[f][2], w, h, stride);
        for (size_t r = 0; r < h; r++) {
            for (size_t k = 0; k < w * c; k++) printf(" %08x", bits(jobs[0].fills[f][r * stride + k]));
            for (size_t k = w * c; k < stride; k++)
                CHECK(jobs[0].fills[f][r * stride + k] == SENTINEL, "padding overwritten");
        }
        printf("\n");
        for (int t = 0; t < 2; t++) free(jobs[t].fills[f]);
    }
    printf("agree %s %d\n", spec, agree);
    surftile_free(s);
}

static void report(const char *name, surftile_status st) {
    const char *message = surftile_last_error();
    CHECK(message != NULL, "%s: null message", name);
    printf("error %s %d %s\n", name, (int)st, message ? message : "");
}

static void *other_thread(void *arg) {
    (void)arg;
    /* Errors are per thread: this thread has had none yet. */
    CHECK(strcmp(surftile_last_error(), "") == 0, "another thread's error leaked: %s",
          surftile_last_error());
    return NULL;
}

static void errors(const char *preset, const char *corrupt) {
    surftile_surface *s = (surftile_surface *)0x1;
    report("missing-file", surftile_open("/nonexistent/surftile/missing.bank", 0, &s));
    CHECK(s == NULL, "missing-file: out not reset to NULL");
    s = (surftile_surface *)0x1;
    report("corrupt-bank", surftile_open(corrupt, 0, &s));
    CHECK(s == NULL, "corrupt-bank: out not reset to NULL");
    report("unknown-preset", surftile_open("no-such-preset", 0, &s));
    report("null-spec", surftile_open(NULL, 0, &s));
    report("null-out", surftile_open(preset, 0, NULL));

    pthread_t t;
    CHECK(pthread_create(&t, NULL, other_thread, NULL) == 0, "pthread_create");
    pthread_join(t, NULL);

    CHECK(surftile_open(preset, 3, &s) == SURFTILE_STATUS_OK, "open %s", preset);
    size_t c = surftile_channels(s);
    float buf[64];
    report("null-surface", surftile_fill(NULL, 0, 0, 1, 4, 4, buf, 4));
    report("null-buffer", surftile_fill(s, 0, 0, 1, 4, 4, NULL, 4 * c));
    report("zero-width", surftile_fill(s, 0, 0, 1, 0, 4, buf, 4 * c));
    report("zero-height", surftile_fill(s, 0, 0, 1, 4, 0, buf, 4 * c));
    report("short-stride", surftile_fill(s, 0, 0, 1, 4, 4, buf, 4 * c - 1));
    report("nan-origin", surftile_fill(s, NAN, 0, 1, 4, 4, buf, 4 * c));
    report("zero-step", surftile_fill(s, 0, 0, 0, 4, 4, buf, 4 * c));
    report("far-origin", surftile_fill(s, 1e300, 0, 1, 4, 4, buf, 4 * c));
    report("huge-size",
           surftile_fill(s, 0, 0, 1e-9, (size_t)1 << 40, (size_t)1 << 30, buf, (size_t)1 << 40));
    float h = surftile_height(NULL, 0, 0);
    CHECK(isnan(h), "height of a null surface is not NaN");
    report("null-height", SURFTILE_STATUS_NULL_POINTER);
    CHECK(surftile_channels(NULL) == 0, "channels of a null surface");
    CHECK(isnan(surftile_spacing_um(NULL)), "spacing of a null surface");
    CHECK(isnan(surftile_height(s, NAN, 0)), "height at NaN is not NaN");
    surftile_free(s);
    surftile_free(NULL);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: check BANK PRESET CORRUPT_BANK\n");
        return 2;
    }
    CHECK(strcmp(surftile_last_error(), "") == 0, "last error before any call");
    printf("abi %u\n", surftile_abi_version());
    CHECK(surftile_abi_version() == SURFTILE_ABI_VERSION, "ABI version differs from the header's");
    sample(argv[1], 7);
    sample(argv[2], 7);
    errors(argv[2], argv[3]);
    return failures == 0 ? 0 : 1;
}
