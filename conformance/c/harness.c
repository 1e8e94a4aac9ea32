/*
 * The MAVLink C library (pymavlink 2.4.50's `mavgen --lang=C --wire-protocol=2.0`
 * output) as the third party of the conformance tests. One process per
 * dialect and run: file in, file out.
 *
 *   harness frames KEYHEX  < cases  > results
 *   harness streams KEYHEX|- 0|1  < streams > accepted
 *
 * Built by conformance/scripts/c-lib.sh with -I to the dialect's generated
 * directory; "dispatch.h" (written by that script) maps message ids to the
 * library's typed functions: mavlink_msg_<name>_encode_status() and
 * mavlink_msg_<name>_decode(). Field values move in and out of the C structs
 * through the library's own field table (MAVLINK_MESSAGE_INFO: name, type,
 * array length, structure offset), so no per-message code is written by hand.
 *
 * Value text (shared with the Rust and Python sides), fields in wire order:
 *   name=value;name=value;...
 * integers in decimal (a scalar char as its byte), float/double as the hex of
 * their IEEE bits (8 / 16 digits), char[N] as the hex of all N bytes, other
 * arrays as comma-separated elements.
 *
 * frames: each input line is
 *   IDX MODE MSGID SEQ SYSID COMPID LINK SIGN_TS VALUES RUSTHEX PYHEX
 * (MODE v2 | v2s | v1). Output per line:
 *   IDX CHEX RDEC PDEC
 * CHEX is the frame the C library packs from VALUES (typed _encode_status,
 * signed with KEYHEX for v2s, MAVLINK_STATUS_FLAG_OUT_MAVLINK1 for v1);
 * RDEC/PDEC are mavlink_parse_char()'s decoding of the Rust and pymavlink
 * frames: "ok:SIG:SEQ:SYSID:COMPID:VALUES" or "rej:REASON", SIG 1 when the
 * signature was verified with the key (v2s), else 0.
 *
 * streams: each input line is one byte stream in hex; output per line: the
 * frames mavlink_parse_char() accepted, in hex, space separated ("-" for
 * none). With a key, signatures are checked (one signing-stream table per
 * input line); the last argument says whether unsigned frames are accepted
 * (accept_unsigned_callback; never for a frame whose signature failed).
 */
#define MAVLINK_USE_MESSAGE_INFO
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdint.h>
#include <stdbool.h>
#include <inttypes.h>

#include "mavlink.h"
#include "mavlink_get_info.h"
#include "dispatch.h"

#define RX_CHAN MAVLINK_COMM_0

static void die(const char *what, long line)
{
    fprintf(stderr, "harness: %s (input line %ld)\n", what, line);
    exit(2);
}

static int hexval(int c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* Hex text (exactly n digits, even) into out; returns bytes or -1. */
static long unhex(const char *s, size_t n, uint8_t *out, size_t cap)
{
    if (n % 2 || n / 2 > cap) return -1;
    for (size_t i = 0; i < n / 2; i++) {
        int hi = hexval((unsigned char)s[2 * i]), lo = hexval((unsigned char)s[2 * i + 1]);
        if (hi < 0 || lo < 0) return -1;
        out[i] = (uint8_t)(hi << 4 | lo);
    }
    return (long)(n / 2);
}

static void puthex(FILE *f, const uint8_t *b, size_t n)
{
    static const char d[] = "0123456789abcdef";
    for (size_t i = 0; i < n; i++) {
        fputc(d[b[i] >> 4], f);
        fputc(d[b[i] & 15], f);
    }
}

static size_t type_size(mavlink_message_type_t t)
{
    switch (t) {
    case MAVLINK_TYPE_CHAR: case MAVLINK_TYPE_UINT8_T: case MAVLINK_TYPE_INT8_T: return 1;
    case MAVLINK_TYPE_UINT16_T: case MAVLINK_TYPE_INT16_T: return 2;
    case MAVLINK_TYPE_UINT32_T: case MAVLINK_TYPE_INT32_T: case MAVLINK_TYPE_FLOAT: return 4;
    default: return 8;
    }
}

/* Writes one scalar element from its text. Returns 0 on success. */
static int put_elem(uint8_t *at, mavlink_message_type_t t, const char *s, size_t n)
{
    char tmp[64];
    if (n == 0 || n >= sizeof tmp) return -1;
    memcpy(tmp, s, n);
    tmp[n] = 0;
    char *end;
    if (t == MAVLINK_TYPE_FLOAT || t == MAVLINK_TYPE_DOUBLE) {
        if (n != 2 * type_size(t)) return -1;
        uint64_t bits = strtoull(tmp, &end, 16);
        if (*end) return -1;
        if (t == MAVLINK_TYPE_FLOAT) {
            uint32_t b32 = (uint32_t)bits;
            memcpy(at, &b32, 4);
        } else {
            memcpy(at, &bits, 8);
        }
        return 0;
    }
    bool is_signed = t == MAVLINK_TYPE_INT8_T || t == MAVLINK_TYPE_INT16_T ||
                     t == MAVLINK_TYPE_INT32_T || t == MAVLINK_TYPE_INT64_T;
    if (is_signed) {
        int64_t v = strtoll(tmp, &end, 10);
        if (*end) return -1;
        memcpy(at, &v, type_size(t)); /* little-endian host: low bytes first */
    } else {
        uint64_t v = strtoull(tmp, &end, 10);
        if (*end) return -1;
        memcpy(at, &v, type_size(t));
    }
    return 0;
}

static const mavlink_field_info_t *find_field(const mavlink_message_info_t *info, const char *name, size_t n)
{
    for (unsigned i = 0; i < info->num_fields; i++) {
        const char *f = info->fields[i].name;
        if (strlen(f) == n && memcmp(f, name, n) == 0) return &info->fields[i];
    }
    return NULL;
}

/* Fills the C struct at `st` from a value text, by the field table. */
static int fill_struct(const mavlink_message_info_t *info, const char *vals, uint8_t *st)
{
    const char *p = vals;
    unsigned seen = 0;
    while (*p) {
        const char *eq = strchr(p, '=');
        if (!eq) return -1;
        const char *end = strchr(eq, ';');
        if (!end) end = eq + strlen(eq);
        const mavlink_field_info_t *f = find_field(info, p, (size_t)(eq - p));
        if (!f) return -1;
        seen++;
        uint8_t *at = st + f->structure_offset;
        const char *v = eq + 1;
        size_t vlen = (size_t)(end - v);
        if (f->type == MAVLINK_TYPE_CHAR && f->array_length > 0) {
            if (unhex(v, vlen, at, f->array_length) != (long)f->array_length) return -1;
        } else if (f->array_length == 0) {
            if (put_elem(at, f->type, v, vlen)) return -1;
        } else {
            size_t sz = type_size(f->type);
            unsigned k = 0;
            const char *e = v;
            while (e < end) {
                const char *c = memchr(e, ',', (size_t)(end - e));
                if (!c) c = end;
                if (k >= f->array_length || put_elem(at + k * sz, f->type, e, (size_t)(c - e))) return -1;
                k++;
                e = c + 1;
            }
            if (k != f->array_length) return -1;
        }
        p = *end ? end + 1 : end;
    }
    return seen == info->num_fields ? 0 : -1;
}

static void print_elem(FILE *out, const uint8_t *at, mavlink_message_type_t t)
{
    switch (t) {
    case MAVLINK_TYPE_CHAR: case MAVLINK_TYPE_UINT8_T: fprintf(out, "%u", at[0]); break;
    case MAVLINK_TYPE_INT8_T: fprintf(out, "%d", (int8_t)at[0]); break;
    case MAVLINK_TYPE_UINT16_T: { uint16_t v; memcpy(&v, at, 2); fprintf(out, "%u", v); break; }
    case MAVLINK_TYPE_INT16_T: { int16_t v; memcpy(&v, at, 2); fprintf(out, "%d", v); break; }
    case MAVLINK_TYPE_UINT32_T: { uint32_t v; memcpy(&v, at, 4); fprintf(out, "%" PRIu32, v); break; }
    case MAVLINK_TYPE_INT32_T: { int32_t v; memcpy(&v, at, 4); fprintf(out, "%" PRId32, v); break; }
    case MAVLINK_TYPE_UINT64_T: { uint64_t v; memcpy(&v, at, 8); fprintf(out, "%" PRIu64, v); break; }
    case MAVLINK_TYPE_INT64_T: { int64_t v; memcpy(&v, at, 8); fprintf(out, "%" PRId64, v); break; }
    case MAVLINK_TYPE_FLOAT: { uint32_t v; memcpy(&v, at, 4); fprintf(out, "%08" PRIx32, v); break; }
    case MAVLINK_TYPE_DOUBLE: { uint64_t v; memcpy(&v, at, 8); fprintf(out, "%016" PRIx64, v); break; }
    }
}

/* Prints the struct's fields in wire order (the table is in XML order). */
static void print_struct(FILE *out, const mavlink_message_info_t *info, const uint8_t *st)
{
    unsigned order[MAVLINK_MAX_FIELDS];
    unsigned n = info->num_fields;
    for (unsigned i = 0; i < n; i++) order[i] = i;
    for (unsigned i = 1; i < n; i++) { /* insertion sort by wire offset */
        unsigned k = order[i], j = i;
        while (j > 0 && info->fields[order[j - 1]].wire_offset > info->fields[k].wire_offset) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = k;
    }
    for (unsigned i = 0; i < n; i++) {
        const mavlink_field_info_t *f = &info->fields[order[i]];
        if (i) fputc(';', out);
        fprintf(out, "%s=", f->name);
        const uint8_t *at = st + f->structure_offset;
        if (f->type == MAVLINK_TYPE_CHAR && f->array_length > 0) {
            puthex(out, at, f->array_length);
        } else if (f->array_length == 0) {
            print_elem(out, at, f->type);
        } else {
            for (unsigned k = 0; k < f->array_length; k++) {
                if (k) fputc(',', out);
                print_elem(out, at + k * type_size(f->type), f->type);
            }
        }
    }
}

/* The exact bytes of a received frame, from the parser's message. */
static size_t frame_bytes(const mavlink_message_t *m, uint8_t *out)
{
    size_t n = 0;
    out[n++] = m->magic;
    out[n++] = m->len;
    if (m->magic == MAVLINK_STX) {
        out[n++] = m->incompat_flags;
        out[n++] = m->compat_flags;
    }
    out[n++] = m->seq;
    out[n++] = m->sysid;
    out[n++] = m->compid;
    out[n++] = (uint8_t)(m->msgid & 0xFF);
    if (m->magic == MAVLINK_STX) {
        out[n++] = (uint8_t)(m->msgid >> 8);
        out[n++] = (uint8_t)(m->msgid >> 16);
    }
    memcpy(out + n, _MAV_PAYLOAD(m), m->len);
    n += m->len;
    out[n++] = m->ck[0];
    out[n++] = m->ck[1];
    if (m->magic == MAVLINK_STX && (m->incompat_flags & MAVLINK_IFLAG_SIGNED)) {
        memcpy(out + n, m->signature, MAVLINK_SIGNATURE_BLOCK_LEN);
        n += MAVLINK_SIGNATURE_BLOCK_LEN;
    }
    return n;
}

static uint8_t key[32];
static bool have_key;
static bool accept_unsigned;
static mavlink_signing_t rx_signing;
static mavlink_signing_streams_t rx_streams;

/* Called for unsigned frames and for frames whose signature failed: accept
   only the former, and only when the policy says so. */
static bool unsigned_cb(const mavlink_status_t *status, uint32_t msgid)
{
    (void)status;
    (void)msgid;
    const mavlink_message_t *rx = mavlink_get_channel_buffer(RX_CHAN);
    return accept_unsigned && !(rx->incompat_flags & MAVLINK_IFLAG_SIGNED);
}

static void rx_reset(bool with_key)
{
    mavlink_status_t *st = mavlink_get_channel_status(RX_CHAN);
    memset(st, 0, sizeof *st);
    memset(mavlink_get_channel_buffer(RX_CHAN), 0, sizeof(mavlink_message_t));
    memset(&rx_signing, 0, sizeof rx_signing);
    memset(&rx_streams, 0, sizeof rx_streams);
    if (with_key) {
        memcpy(rx_signing.secret_key, key, 32);
        rx_signing.accept_unsigned_callback = unsigned_cb;
        st->signing = &rx_signing;
        st->signing_streams = &rx_streams;
    }
}

/* Decodes one whole frame with mavlink_parse_char; prints the result token. */
static void decode_frame(FILE *out, const char *hex, bool signed_mode)
{
    uint8_t buf[600];
    long n = unhex(hex, strlen(hex), buf, sizeof buf);
    if (n < 0) { fputs("rej:badhex", out); return; }
    rx_reset(signed_mode);
    accept_unsigned = false;
    mavlink_message_t msg;
    mavlink_status_t status;
    int got = 0;
    long at = -1;
    for (long i = 0; i < n; i++) {
        if (mavlink_parse_char(RX_CHAN, buf[i], &msg, &status)) { got++; at = i; }
    }
    if (got != 1 || at != n - 1) { fprintf(out, "rej:frames=%d", got); return; }
    const mavlink_message_info_t *info = mavlink_get_message_info(&msg);
    if (!info) { fputs("rej:noinfo", out); return; }
    union { uint8_t b[MAVLINK_MAX_PAYLOAD_LEN + 8]; uint64_t align; } st;
    memset(&st, 0, sizeof st);
    if (!typed_decode(&msg, st.b)) { fputs("rej:nodecode", out); return; }
    bool sig = signed_mode && (msg.incompat_flags & MAVLINK_IFLAG_SIGNED) &&
               rx_signing.last_status == MAVLINK_SIGNING_STATUS_OK;
    fprintf(out, "ok:%d:%u:%u:%u:", sig ? 1 : 0, msg.seq, msg.sysid, msg.compid);
    print_struct(out, info, st.b);
}

static int cmd_frames(void)
{
    char *line = NULL;
    size_t cap = 0;
    long lineno = 0;
    while (getline(&line, &cap, stdin) > 0) {
        lineno++;
        char *tok[11];
        int nt = 0;
        for (char *s = strtok(line, " \n"); s && nt < 11; s = strtok(NULL, " \n")) tok[nt++] = s;
        if (nt != 11) die("expected 11 fields", lineno);
        const char *mode = tok[1];
        uint32_t msgid = (uint32_t)strtoul(tok[2], NULL, 10);
        uint8_t seq = (uint8_t)atoi(tok[3]), sysid = (uint8_t)atoi(tok[4]), compid = (uint8_t)atoi(tok[5]);
        uint8_t link = (uint8_t)atoi(tok[6]);
        uint64_t ts = strtoull(tok[7], NULL, 10);
        bool v1 = strcmp(mode, "v1") == 0, sign = strcmp(mode, "v2s") == 0;

        const mavlink_message_info_t *info = mavlink_get_message_info_by_id(msgid);
        if (!info) die("message id unknown to the C library", lineno);
        union { uint8_t b[MAVLINK_MAX_PAYLOAD_LEN + 8]; uint64_t align; } st;
        memset(&st, 0, sizeof st);
        if (fill_struct(info, tok[8], st.b)) die("bad value text", lineno);

        mavlink_status_t tx;
        memset(&tx, 0, sizeof tx);
        mavlink_signing_t tx_signing;
        memset(&tx_signing, 0, sizeof tx_signing);
        tx.current_tx_seq = seq;
        if (v1) tx.flags |= MAVLINK_STATUS_FLAG_OUT_MAVLINK1;
        if (sign) {
            tx_signing.flags = MAVLINK_SIGNING_FLAG_SIGN_OUTGOING;
            tx_signing.link_id = link;
            tx_signing.timestamp = ts;
            memcpy(tx_signing.secret_key, key, 32);
            tx.signing = &tx_signing;
        }
        mavlink_message_t msg;
        memset(&msg, 0, sizeof msg);
        if (!typed_encode(msgid, sysid, compid, &tx, &msg, st.b)) die("no typed encoder", lineno);
        uint8_t out[MAVLINK_MAX_PACKET_LEN];
        uint16_t n = mavlink_msg_to_send_buffer(out, &msg);

        fputs(tok[0], stdout);
        fputc(' ', stdout);
        puthex(stdout, out, n);
        fputc(' ', stdout);
        decode_frame(stdout, tok[9], sign);
        fputc(' ', stdout);
        decode_frame(stdout, tok[10], sign);
        fputc('\n', stdout);
    }
    free(line);
    return 0;
}

static int cmd_streams(void)
{
    char *line = NULL;
    size_t cap = 0;
    long lineno = 0;
    uint8_t *buf = NULL;
    size_t bufcap = 0;
    while (getline(&line, &cap, stdin) > 0) {
        lineno++;
        size_t len = strcspn(line, " \n");
        if (len / 2 > bufcap) {
            bufcap = len / 2 + 1;
            buf = realloc(buf, bufcap);
            if (!buf) die("out of memory", lineno);
        }
        long n = unhex(line, len, buf, bufcap);
        if (n < 0) die("bad hex", lineno);
        rx_reset(have_key);
        mavlink_message_t msg;
        mavlink_status_t status;
        int frames = 0;
        for (long i = 0; i < n; i++) {
            if (mavlink_parse_char(RX_CHAN, buf[i], &msg, &status) == MAVLINK_FRAMING_OK) {
                uint8_t fb[MAVLINK_MAX_PACKET_LEN + 16];
                size_t fl = frame_bytes(&msg, fb);
                if (frames++) fputc(' ', stdout);
                puthex(stdout, fb, fl);
            }
        }
        if (!frames) fputc('-', stdout);
        fputc('\n', stdout);
    }
    free(buf);
    free(line);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: harness frames KEYHEX | harness streams KEYHEX|- 0|1\n");
        return 2;
    }
    if (strcmp(argv[2], "-") != 0) {
        if (unhex(argv[2], strlen(argv[2]), key, 32) != 32) die("key must be 64 hex digits", 0);
        have_key = true;
    }
    if (strcmp(argv[1], "frames") == 0) return cmd_frames();
    if (strcmp(argv[1], "streams") == 0 && argc == 4) {
        accept_unsigned = atoi(argv[3]) != 0;
        return cmd_streams();
    }
    fprintf(stderr, "harness: unknown command\n");
    return 2;
}
