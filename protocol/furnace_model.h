/*
 * furnace_model.h - helpers for a furnace model server (protocol version 1), C99, libc only.
 *
 * furnace runs its model-level checks (reciprocity, energy, albedo, chi-square, sample
 * weights, phase functions, emitter sampling) on a renderer's own BSDF, phase-function and
 * emitter code through a small process that answers batched queries on stdin/stdout. The
 * contract is docs/model-protocol.md; protocol/example_server.c is a complete server built
 * on this header. In short:
 *
 *   request  = one JSON header line  {"op":"bsdf.eval","model":"diffuse/0.5","n":N,"width":W}
 *              followed by N*W little-endian IEEE-754 doubles (no payload without "n");
 *   reply    = {"ok":true,"n":N,"width":W'} + N*W' doubles, or {"ok":false,"error":"..."}.
 *
 * This header gives a renderer team what it needs without a JSON library:
 *
 *   fm_read_request()   reads one header line and extracts op, model, n, width (and the hello
 *                       request's protocol number), then reads the payload into a malloc'ed
 *                       array of doubles, converted from little-endian on any host;
 *   fm_write_reply()    writes {"ok":true,"n":..,"width":..} and the reply payload;
 *   fm_write_error()    writes {"ok":false,"error":"..."} (the message is JSON-escaped);
 *   fm_write_json_string() writes an escaped JSON string, for building the hello reply;
 *   fm_write_doubles()  writes little-endian doubles.
 *
 * Everything is `static inline`: include the header in one or more .c files, no library to
 * link. fm_read_request keeps the header line in a static buffer: call it from one thread.
 * Streams must be binary (on Windows call _setmode(_fileno(stdin/stdout), _O_BINARY)).
 * Replies must be flushed (fm_write_reply and fm_write_error do); log to stderr, never stdout.
 *
 * The JSON reader accepts any valid header object (keys in any order, whitespace, escapes
 * including \uXXXX surrogate pairs decoded to UTF-8, nested values skipped) but extracts only
 * the keys above; values of other keys are ignored.
 */
#ifndef FURNACE_MODEL_H
#define FURNACE_MODEL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FM_PROTOCOL 1
/** Largest batch a request may carry (docs/model-protocol.md, "Transport"). */
#define FM_MAX_ROWS 1048576u
/** Largest row width this header accepts (the widest request row is 10). */
#define FM_MAX_WIDTH 64u
/** Longest header line accepted, in bytes. */
#define FM_MAX_LINE 65536u

/** One request: the header's keys of interest and its payload. */
typedef struct {
    char op[64];          /**< "hello", "bsdf.eval", ... ("" if absent) */
    char model[512];      /**< model name, UTF-8 ("" if absent) */
    int protocol;         /**< "protocol" of a hello request, -1 if absent */
    int has_payload;      /**< 1 when the header had "n" (then n, width, rows are set) */
    size_t n;             /**< number of rows */
    size_t width;         /**< doubles per row */
    double *rows;         /**< n*width doubles in host order, row-major; free with fm_free */
} fm_request;

/* ------------------------------------------------------------------------------------------ */
/* byte order                                                                                 */
/* ------------------------------------------------------------------------------------------ */

static inline int fm_host_is_little_endian(void) {
    const uint16_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 1;
}

/** Reverses the 8 bytes of each of `count` doubles in place (only on big-endian hosts). */
static inline void fm_to_from_le(double *v, size_t count) {
    size_t i;
    if (fm_host_is_little_endian()) return;
    for (i = 0; i < count; i++) {
        unsigned char b[8], t;
        int k;
        memcpy(b, &v[i], 8);
        for (k = 0; k < 4; k++) { t = b[k]; b[k] = b[7 - k]; b[7 - k] = t; }
        memcpy(&v[i], b, 8);
    }
}

/** Writes `count` doubles little-endian. Returns 0 on success, -1 on a write error. */
static inline int fm_write_doubles(FILE *out, const double *v, size_t count) {
    if (count == 0) return 0;
    if (fm_host_is_little_endian())
        return fwrite(v, sizeof(double), count, out) == count ? 0 : -1;
    {
        size_t i;
        for (i = 0; i < count; i++) {
            double d = v[i];
            fm_to_from_le(&d, 1);
            if (fwrite(&d, sizeof(double), 1, out) != 1) return -1;
        }
    }
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* minimal JSON reading (a flat object; nested values are skipped)                           */
/* ------------------------------------------------------------------------------------------ */

static inline const char *fm_skip_ws(const char *p) {
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
    return p;
}

static inline int fm_hex4(const char *p, unsigned *out) {
    unsigned v = 0;
    int i;
    for (i = 0; i < 4; i++) {
        char c = p[i];
        v <<= 4;
        if (c >= '0' && c <= '9') v |= (unsigned)(c - '0');
        else if (c >= 'a' && c <= 'f') v |= (unsigned)(c - 'a' + 10);
        else if (c >= 'A' && c <= 'F') v |= (unsigned)(c - 'A' + 10);
        else return -1;
    }
    *out = v;
    return 0;
}

/* Appends code point `cp` as UTF-8 to dst (capacity cap, length *len); drops what does not fit
   and sets *overflow. */
static inline void fm_put_utf8(char *dst, size_t cap, size_t *len, unsigned long cp,
                               int *overflow) {
    unsigned char b[4];
    size_t k, m;
    if (cp < 0x80) { b[0] = (unsigned char)cp; m = 1; }
    else if (cp < 0x800) { b[0] = (unsigned char)(0xC0 | (cp >> 6));
                           b[1] = (unsigned char)(0x80 | (cp & 0x3F)); m = 2; }
    else if (cp < 0x10000) { b[0] = (unsigned char)(0xE0 | (cp >> 12));
                             b[1] = (unsigned char)(0x80 | ((cp >> 6) & 0x3F));
                             b[2] = (unsigned char)(0x80 | (cp & 0x3F)); m = 3; }
    else { b[0] = (unsigned char)(0xF0 | (cp >> 18));
           b[1] = (unsigned char)(0x80 | ((cp >> 12) & 0x3F));
           b[2] = (unsigned char)(0x80 | ((cp >> 6) & 0x3F));
           b[3] = (unsigned char)(0x80 | (cp & 0x3F)); m = 4; }
    if (*len + m + 1 > cap) { *overflow = 1; return; }
    for (k = 0; k < m; k++) dst[(*len)++] = (char)b[k];
}

/* Parses the JSON string at p (which points at the opening quote) into dst (NUL-terminated,
   may be NULL to skip). Returns the position after the closing quote, or NULL on a syntax
   error; *overflow is set when dst was too small. */
static inline const char *fm_parse_string(const char *p, char *dst, size_t cap, int *overflow) {
    size_t len = 0;
    char scratch[8];
    if (*p != '"') return NULL;
    p++;
    if (!dst) { dst = scratch; cap = sizeof scratch; }
    for (;;) {
        unsigned char c = (unsigned char)*p;
        if (dst == scratch) len = 0;   /* skipping: keep nothing */
        if (c == 0 || c < 0x20) return NULL;
        if (c == '"') { p++; break; }
        if (c != '\\') {
            if (len + 2 <= cap) dst[len++] = (char)c;
            else *overflow = 1;
            p++;
            continue;
        }
        p++;
        switch (*p) {
        case '"': case '\\': case '/':
            fm_put_utf8(dst, cap, &len, (unsigned char)*p, overflow); p++; break;
        case 'b': fm_put_utf8(dst, cap, &len, '\b', overflow); p++; break;
        case 'f': fm_put_utf8(dst, cap, &len, '\f', overflow); p++; break;
        case 'n': fm_put_utf8(dst, cap, &len, '\n', overflow); p++; break;
        case 'r': fm_put_utf8(dst, cap, &len, '\r', overflow); p++; break;
        case 't': fm_put_utf8(dst, cap, &len, '\t', overflow); p++; break;
        case 'u': {
            unsigned hi, lo;
            unsigned long cp;
            if (fm_hex4(p + 1, &hi)) return NULL;
            p += 5;
            cp = hi;
            if (hi >= 0xD800 && hi <= 0xDBFF) {   /* UTF-16 surrogate pair (RFC 8259 §7) */
                if (p[0] != '\\' || p[1] != 'u' || fm_hex4(p + 2, &lo) || lo < 0xDC00 ||
                    lo > 0xDFFF)
                    return NULL;
                p += 6;
                cp = 0x10000ul + (((unsigned long)hi - 0xD800u) << 10) + (lo - 0xDC00u);
            }
            fm_put_utf8(dst, cap, &len, cp, overflow);
            break;
        }
        default: return NULL;
        }
    }
    if (dst != scratch) dst[len] = 0;
    return p;
}

/* Skips any JSON value at p; returns the position after it or NULL. */
static inline const char *fm_skip_value(const char *p) {
    int depth = 0, ov = 0;
    p = fm_skip_ws(p);
    do {
        p = fm_skip_ws(p);
        if (*p == '"') {
            p = fm_parse_string(p, NULL, 0, &ov);
            if (!p) return NULL;
        } else if (*p == '{' || *p == '[') {
            depth++; p++;
        } else if (*p == '}' || *p == ']') {
            if (depth == 0) return NULL;
            depth--; p++;
        } else if (*p == ',' || *p == ':') {
            if (depth == 0) return NULL;
            p++;
        } else if (*p == 0) {
            return NULL;
        } else {   /* number, true, false, null */
            const char *q = p;
            while (*p && !strchr(" \t\r\n,:]}[{\"", *p)) p++;
            if (p == q) return NULL;
        }
    } while (depth > 0);
    return p;
}

/* Parses a non-negative integer JSON number (no fraction or exponent). */
static inline const char *fm_parse_size(const char *p, size_t *out) {
    size_t v = 0;
    if (*p < '0' || *p > '9') return NULL;
    while (*p >= '0' && *p <= '9') {
        if (v > ((size_t)-1 - 9) / 10) return NULL;
        v = v * 10 + (size_t)(*p - '0');
        p++;
    }
    if (*p == '.' || *p == 'e' || *p == 'E') return NULL;
    *out = v;
    return p;
}

/**
 * Extracts op, model, n, width and protocol from one header line (NUL-terminated).
 * Returns 0, or -1 with a message in err (capacity errcap).
 */
static inline int fm_parse_header(const char *line, fm_request *req, char *err, size_t errcap) {
    const char *p = fm_skip_ws(line);
    int have_n = 0, have_w = 0;
    memset(req, 0, sizeof *req);
    req->protocol = -1;
    if (*p != '{') { snprintf(err, errcap, "header is not a JSON object"); return -1; }
    p = fm_skip_ws(p + 1);
    if (*p == '}') p = fm_skip_ws(p + 1);
    else for (;;) {
        char key[32];
        int ov = 0;
        p = fm_parse_string(p, key, sizeof key, &ov);
        if (!p) { snprintf(err, errcap, "bad key in header"); return -1; }
        p = fm_skip_ws(p);
        if (*p != ':') { snprintf(err, errcap, "missing ':' in header"); return -1; }
        p = fm_skip_ws(p + 1);
        if (!ov && (strcmp(key, "op") == 0 || strcmp(key, "model") == 0) && *p == '"') {
            int is_op = strcmp(key, "op") == 0;
            int ov2 = 0;
            p = fm_parse_string(p, is_op ? req->op : req->model,
                                is_op ? sizeof req->op : sizeof req->model, &ov2);
            if (!p || ov2) { snprintf(err, errcap, "bad or too long \"%s\"", key); return -1; }
        } else if (!ov && (strcmp(key, "n") == 0 || strcmp(key, "width") == 0)) {
            size_t v;
            p = fm_parse_size(p, &v);
            if (!p) { snprintf(err, errcap, "\"%s\" is not a non-negative integer", key); return -1; }
            if (key[0] == 'n') { req->n = v; have_n = 1; } else { req->width = v; have_w = 1; }
        } else if (!ov && strcmp(key, "protocol") == 0 && *p >= '0' && *p <= '9') {
            size_t v;
            p = fm_parse_size(p, &v);
            if (!p) { snprintf(err, errcap, "bad \"protocol\""); return -1; }
            req->protocol = v > 1000000u ? 1000000 : (int)v;
        } else {
            p = fm_skip_value(p);
            if (!p) { snprintf(err, errcap, "bad value for key \"%s\"", key); return -1; }
        }
        p = fm_skip_ws(p);
        if (*p == ',') { p = fm_skip_ws(p + 1); continue; }
        if (*p == '}') { p = fm_skip_ws(p + 1); break; }
        snprintf(err, errcap, "expected ',' or '}' in header");
        return -1;
    }
    if (*p != 0) { snprintf(err, errcap, "text after the header object"); return -1; }
    if (have_n != have_w) { snprintf(err, errcap, "\"n\" and \"width\" go together"); return -1; }
    req->has_payload = have_n;
    return 0;
}

/* ------------------------------------------------------------------------------------------ */
/* reading a request                                                                          */
/* ------------------------------------------------------------------------------------------ */

/** Frees the payload of a request. */
static inline void fm_free(fm_request *req) {
    free(req->rows);
    req->rows = NULL;
}

/* Reads and discards `bytes` bytes (the payload of a request that is rejected). */
static inline int fm_discard(FILE *in, size_t bytes) {
    char buf[4096];
    while (bytes > 0) {
        size_t k = bytes < sizeof buf ? bytes : sizeof buf;
        if (fread(buf, 1, k, in) != k) return -1;
        bytes -= k;
    }
    return 0;
}

/**
 * Reads one request (header line and payload) from `in`.
 * Returns  1: a request is in *req (free its rows with fm_free);
 *          0: end of input (furnace closed the stream: exit normally);
 *         -1: a request that must be answered with fm_write_error(err) - its payload, if the
 *             header announced one within limits, has been consumed, so serving may go on;
 *         -2: the stream cannot be read further (unparseable header, short payload): answer
 *             with fm_write_error(err) if possible and exit.
 */
static inline int fm_read_request(FILE *in, fm_request *req, char *err, size_t errcap) {
    static char line[FM_MAX_LINE + 2];
    size_t len = 0;
    int c;
    memset(req, 0, sizeof *req);
    req->protocol = -1;
    while ((c = fgetc(in)) != EOF && c != '\n') {
        if (len >= FM_MAX_LINE) { snprintf(err, errcap, "header line too long"); return -2; }
        line[len++] = (char)c;
    }
    if (c == EOF && len == 0) return 0;
    if (c == EOF) { snprintf(err, errcap, "header line without newline"); return -2; }
    line[len] = 0;
    if (memchr(line, 0, len)) { snprintf(err, errcap, "NUL byte in header"); return -2; }
    if (fm_parse_header(line, req, err, errcap)) return -2;
    if (!req->has_payload) return 1;
    if (req->width == 0 || req->width > FM_MAX_WIDTH) {
        snprintf(err, errcap, "width %lu outside 1..%u", (unsigned long)req->width, FM_MAX_WIDTH);
        return -2;   /* could be anything: do not try to skip it */
    }
    if (req->n > FM_MAX_ROWS) {   /* a client this far off the protocol: stop */
        snprintf(err, errcap, "batch of %lu rows exceeds %u", (unsigned long)req->n, FM_MAX_ROWS);
        return -2;
    }
    req->rows = (double *)malloc(req->n * req->width * sizeof(double) + 1);
    if (!req->rows) {
        snprintf(err, errcap, "out of memory for %lu rows", (unsigned long)req->n);
        return fm_discard(in, req->n * req->width * 8) ? -2 : -1;
    }
    if (fread(req->rows, sizeof(double), req->n * req->width, in) != req->n * req->width) {
        fm_free(req);
        snprintf(err, errcap, "payload shorter than announced");
        return -2;
    }
    fm_to_from_le(req->rows, req->n * req->width);
    return 1;
}

/* ------------------------------------------------------------------------------------------ */
/* writing replies                                                                            */
/* ------------------------------------------------------------------------------------------ */

/** Writes `s` as a JSON string (quotes included; control characters, '"' and '\' escaped,
    other UTF-8 bytes passed through). */
static inline void fm_write_json_string(FILE *out, const char *s) {
    fputc('"', out);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') { fputc('\\', out); fputc(c, out); }
        else if (c == '\n') fputs("\\n", out);
        else if (c == '\t') fputs("\\t", out);
        else if (c < 0x20) fprintf(out, "\\u%04x", c);
        else fputc(c, out);
    }
    fputc('"', out);
}

/** Writes {"ok":true,"n":n,"width":width} and n*width doubles (host order in `rows`). */
static inline int fm_write_reply(FILE *out, size_t n, size_t width, const double *rows) {
    fprintf(out, "{\"ok\":true,\"n\":%lu,\"width\":%lu}\n", (unsigned long)n,
            (unsigned long)width);
    if (fm_write_doubles(out, rows, n * width)) return -1;
    return fflush(out) == 0 ? 0 : -1;
}

/** Writes {"ok":false,"error":msg}. */
static inline int fm_write_error(FILE *out, const char *msg) {
    fputs("{\"ok\":false,\"error\":", out);
    fm_write_json_string(out, msg);
    fputs("}\n", out);
    return fflush(out) == 0 ? 0 : -1;
}

#endif /* FURNACE_MODEL_H */
