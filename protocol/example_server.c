/*
 * example_server.c - a complete furnace model server (protocol 1, docs/model-protocol.md) in
 * C99, for a renderer team to copy: replace the three models with calls into your renderer.
 *
 *   cc -std=c99 -Wall -Wextra -O2 protocol/example_server.c -o /tmp/example_server -lm
 *
 * Models: "diffuse/0.5" (a correct Lambertian), "diffuse/0.5 without 1/pi" (a deliberately
 * wrong one that furnace must reject: a negative control) and "hg g=0.5" (Henyey-Greenstein).
 * Local shading frame, z = normal; wo and wi point away from the surface / scattering point.
 */
#include <math.h>
#include "furnace_model.h"

#define PI 3.14159265358979323846

typedef struct { double x, y, z; } v3;

static const char *HELLO =
    "{\"ok\":true,\"protocol\":1,\"renderer\":\"furnace C example\",\"version\":\"1\","
    "\"models\":["
    "{\"name\":\"diffuse/0.5\",\"kind\":\"bsdf\",\"params\":{\"type\":\"diffuse\",\"reflectance\":0.5},"
    "\"flags\":{\"delta\":false,\"two_sided\":false,\"transmission\":false,\"eta\":1.0,"
    "\"lossless\":false,\"dispersive\":false,\"min_roughness\":null}},"
    "{\"name\":\"diffuse/0.5 without 1/pi\",\"kind\":\"bsdf\",\"params\":{\"type\":\"diffuse\","
    "\"reflectance\":0.5,\"bug\":\"eval lacks 1/pi (negative control)\"},"
    "\"flags\":{\"delta\":false,\"two_sided\":false,\"transmission\":false,\"eta\":1.0,"
    "\"lossless\":false,\"dispersive\":false,\"min_roughness\":null}},"
    "{\"name\":\"hg g=0.5\",\"kind\":\"phase\",\"params\":{\"type\":\"hg\",\"g\":0.5},"
    "\"flags\":{\"mean_cosine\":0.5}}]}\n";

static v3 get3(const double *r) { v3 v = {r[0], r[1], r[2]}; return v; }

/* Lambertian: f = rho/pi for wo, wi both above (Lambert 1760); `scale` = 1/pi, or 1 for the
   negative control. pdf = cos(theta_i)/pi, the cosine-weighted hemisphere. */
static double lambert_f(v3 wo, v3 wi, double scale) {
    return (wo.z > 0 && wi.z > 0) ? 0.5 * scale : 0.0;
}
static double lambert_pdf(v3 wo, v3 wi) { return (wo.z > 0 && wi.z > 0) ? wi.z / PI : 0.0; }

/* Cosine-weighted hemisphere by Malley's method: a uniform disk point (r = sqrt(u1),
   phi = 2 pi u2) lifted to the hemisphere (Pharr, Jakob & Humphreys, PBR 3rd ed., §13.6.3). */
static v3 cosine_hemisphere(double u1, double u2) {
    double r = sqrt(u1), phi = 2.0 * PI * u2;
    v3 w = {r * cos(phi), r * sin(phi), sqrt(fmax(0.0, 1.0 - u1))};
    return w;
}

/* Henyey-Greenstein with mu = -wo.wi the scattering cosine (forward: wi = -wo), in the stable
   form p = (1-g^2) / (4 pi ((1-g)^2 + 2g(1-mu))^(3/2)) (Henyey & Greenstein 1941, eq. 3). */
static double hg_p(double g, v3 wo, v3 wi) {
    double mu = -(wo.x * wi.x + wo.y * wi.y + wo.z * wi.z);
    double d = (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu);
    return (1.0 - g * g) / (4.0 * PI * d * sqrt(d));
}

/* Orthonormal basis around n (Duff et al. 2017, JCGT 6(1), "Building an Orthonormal Basis,
   Revisited", listing 3). */
static void basis(v3 n, v3 *t, v3 *b) {
    double s = n.z >= 0 ? 1.0 : -1.0, a = -1.0 / (s + n.z), c = n.x * n.y * a;
    t->x = 1.0 + s * n.x * n.x * a; t->y = s * c; t->z = -s * n.x;
    b->x = c; b->y = s + n.y * n.y * a; b->z = -n.y;
}

/* Samples the scattering cosine by inverting the HG cdf (Pharr, Jakob & Humphreys, PBR 3rd ed.,
   eq. 15.7; isotropic when g = 0), then a uniform azimuth about the forward axis -wo. */
static v3 hg_sample(double g, v3 wo, double u1, double u2) {
    double mu, s, phi;
    v3 f = {-wo.x, -wo.y, -wo.z}, t, b, wi;
    if (fabs(g) < 1e-3) mu = 1.0 - 2.0 * u1;
    else {
        double q = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        mu = (1.0 + g * g - q * q) / (2.0 * g);
    }
    mu = fmin(1.0, fmax(-1.0, mu));
    s = sqrt(fmax(0.0, 1.0 - mu * mu));
    phi = 2.0 * PI * u2;
    basis(f, &t, &b);
    wi.x = mu * f.x + s * (cos(phi) * t.x + sin(phi) * b.x);
    wi.y = mu * f.y + s * (cos(phi) * t.y + sin(phi) * b.y);
    wi.z = mu * f.z + s * (cos(phi) * t.z + sin(phi) * b.z);
    return wi;
}

/* The ops this server knows: request and reply row widths (docs/model-protocol.md). */
static const struct { const char *op; size_t in, out; int phase; } OPS[] = {
    {"bsdf.eval", 10, 4, 0}, {"bsdf.pdf", 10, 1, 0}, {"bsdf.sample", 10, 9, 0},
    {"phase.eval", 10, 1, 1}, {"phase.pdf", 10, 1, 1}, {"phase.sample", 9, 5, 1}};

/* Answers one request into `out` (n rows of the reply width); returns the reply width, or 0
   with a message in err. */
static size_t serve(const fm_request *q, double *out, char *err, size_t errcap) {
    int wrong = !strcmp(q->model, "diffuse/0.5 without 1/pi");
    int bsdf = wrong || !strcmp(q->model, "diffuse/0.5"), phase = !strcmp(q->model, "hg g=0.5");
    double scale = wrong ? 1.0 : 1.0 / PI, g = 0.5;
    size_t k, i, w;
    for (k = 0; k < sizeof OPS / sizeof OPS[0] && strcmp(OPS[k].op, q->op); k++) {}
    if (k == sizeof OPS / sizeof OPS[0] && strncmp(q->op, "emitter.", 8)) {
        snprintf(err, errcap, "unknown op %s", q->op); return 0; }
    if (!bsdf && !phase) { snprintf(err, errcap, "unknown model %s", q->model); return 0; }
    if (k == sizeof OPS / sizeof OPS[0] || OPS[k].phase != phase) {
        snprintf(err, errcap, "op %s does not apply to model %s", q->op, q->model); return 0; }
    if (!q->has_payload || q->width != OPS[k].in) {
        snprintf(err, errcap, "op %s takes rows of %lu f64", q->op, (unsigned long)OPS[k].in);
        return 0; }
    w = OPS[k].out;
    for (i = 0; i < q->n; i++) {
        const double *r = q->rows + i * q->width;
        v3 wo = get3(r), wi = get3(r + 3);
        double *o = out + i * w;
        memset(o, 0, w * sizeof *o);
        if (k == 0) {                               /* bsdf.eval: f[4], no cosine */
            o[0] = o[1] = o[2] = o[3] = lambert_f(wo, wi, scale);
        } else if (k == 1) {                        /* bsdf.pdf */
            o[0] = lambert_pdf(wo, wi);
        } else if (k == 2 && wo.z > 0) {            /* bsdf.sample: wi, weight[4], pdf, flags */
            v3 s = cosine_hemisphere(r[3], r[4]);
            double pdf = lambert_pdf(wo, s);
            if (pdf > 0) {                          /* weight = f cos / pdf; flags 0 = none */
                o[0] = s.x; o[1] = s.y; o[2] = s.z;
                o[3] = o[4] = o[5] = o[6] = lambert_f(wo, s, scale) * s.z / pdf;
                o[7] = pdf; o[8] = 1;
            }
        } else if (k == 3 || k == 4) {              /* phase.eval, phase.pdf */
            o[0] = hg_p(g, wo, wi);
        } else if (k == 5) {                        /* phase.sample: wi, weight, pdf */
            v3 s = hg_sample(g, wo, r[3], r[4]);
            o[0] = s.x; o[1] = s.y; o[2] = s.z; o[3] = 1.0; o[4] = hg_p(g, wo, s);
        }
    }
    return w;
}

int main(void) {
    fm_request q;
    char err[1024];   /* room for an op and a model name */
    int rc;
    while ((rc = fm_read_request(stdin, &q, err, sizeof err)) != 0) {
        if (rc == -2) { fm_write_error(stdout, err); return 2; }
        if (rc == -1) { fm_write_error(stdout, err); continue; }
        if (!strcmp(q.op, "bye")) { fm_free(&q); break; }
        if (!strcmp(q.op, "hello")) {
            if (q.protocol != FM_PROTOCOL)
                fprintf(stderr, "example server: client protocol %d, mine %d\n", q.protocol,
                        FM_PROTOCOL);
            fputs(HELLO, stdout);
            fflush(stdout);
        } else {
            double *out = (double *)malloc((q.has_payload ? q.n : 0) * 9 * sizeof(double) + 8);
            size_t w = out ? serve(&q, out, err, sizeof err) : 0;
            if (!out) snprintf(err, sizeof err, "out of memory");
            if (w) fm_write_reply(stdout, q.n, w, out);
            else fm_write_error(stdout, err);
            free(out);
        }
        fm_free(&q);
    }
    return 0;
}
