/*
 * Load source and checking sink for benches/scripts/router_compare.sh: UDP
 * routers measured side by side on 127.0.0.1. Each phase runs in slices
 * (env ROUTER_LOAD_SLICES, default 6): in every slice each router takes the
 * load in turn for the slice's share of the phase, so a slow spell of a
 * shared machine hits all alike, and the slices of one router next to
 * another's give paired ratios whose spread shows the noise.
 *
 *   router_load NAME:PID:IN_PORT:OUT_PORT [NAME:PID:IN_PORT:OUT_PORT ...]
 *
 * The router under test reads datagrams on IN_PORT and sends what it routes
 * to OUT_PORT, where this program's sink listens. The frames are MAVLink 2,
 * unsigned, six ArduPlane telemetry types (HEARTBEAT, SYS_STATUS, RAW_IMU,
 * ATTITUDE, GLOBAL_POSITION_INT, VFR_HUD) from systems 1-4 in turn, each
 * with its own sequence; the first four payload bytes carry a run-unique
 * counter ((slice id mod 64) << 26 | index), so the sink can count per
 * slice, check order per system and look up the send time for the latency.
 *
 * The sink checks every frame it gets: start byte, length, CRC with the
 * type's CRC_EXTRA, a counter of the current slice, order per system. It
 * runs in a thread of its own (recvmmsg) beside the sender.
 *
 * Phases (whole durations, split into the slices; scaled by env
 * ROUTER_LOAD_SCALE, default 1; env ROUTER_LOAD_ONLY=NAME runs that phase
 * alone):
 *   sat1    3 s  as fast as sendmmsg goes, one frame per datagram
 *   sat10   3 s  as fast as sendmmsg goes, ten frames per datagram
 *   r2000   4 s  2,000 frames/s, one per datagram, paced
 *   r20000  3 s  20,000 frames/s, one per datagram, paced
 *   lat1000 3 s  1,000 frames/s; latency from the send-time table
 *
 * One line per router and slice of each phase on stdout (fields named in
 * the header line): frames sent, frames the router read (sent minus the datagrams the
 * kernel dropped at its input socket), frames delivered to the sink, the
 * sink's bad, stale and out-of-order frames, drops at each socket (from
 * /proc/net/udp), the router's CPU from /proc/PID/stat (utime + stime, in
 * clock ticks) and from the schedstat of every thread under /proc/PID/task (ns),
 * the time the load was sent for, the time the CPU was measured over
 * (the load and the drain after it) and the latency median and p99 in
 * microseconds.
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define MAX_ROUTERS 4
#define SYSTEMS 4
#define TYPES 6
#define BATCH 32
#define MAX_PER_DGRAM 10
#define FRAME_MAX 280
#define LAT_MAX 65536

struct msg_type {
    uint32_t id;
    uint8_t len, crc_extra;
};

/* Lengths as ArduPlane sends them (extensions it sets kept, zeros cut). */
static const struct msg_type TYPES_[TYPES] = {
    {0, 9, 50},    /* HEARTBEAT */
    {1, 31, 124},  /* SYS_STATUS */
    {27, 29, 144}, /* RAW_IMU, with temperature */
    {30, 28, 39},  /* ATTITUDE */
    {33, 28, 104}, /* GLOBAL_POSITION_INT */
    {74, 20, 20},  /* VFR_HUD */
};

struct router {
    char name[32];
    int pid, in_port, out_port, sink_fd;
};

struct phase {
    const char *name;
    double secs;
    int per_dgram;
    int rate; /* frames/s; 0: as fast as it goes */
    int latency;
    double drain; /* s after the load, for what the router still holds */
};

static const struct phase PHASES[] = {
    {"sat1", 3, 1, 0, 0, 0.3},     {"sat10", 3, 10, 0, 0, 0.3},
    {"r2000", 4, 1, 2000, 0, 0.05}, {"r20000", 3, 1, 20000, 0, 0.05},
    {"lat1000", 3, 1, 1000, 1, 0.05},
};
#define NPHASES (sizeof PHASES / sizeof PHASES[0])

/* What the sink counts, per router (a late frame of one router's slice
 * is never charged to the next); reset by the sender as each slice of
 * that router starts. */
static struct {
    atomic_uint_fast64_t good[MAX_ROUTERS], bad[MAX_ROUTERS], stale[MAX_ROUTERS],
        disorder[MAX_ROUTERS];
    atomic_uint phase_id; /* counter >> 26 of the current slice */
    atomic_int lat_on;
    atomic_int stop;
} sink;
/* The sink's alone: the last counter per system, of the slice in seen_id. */
static uint32_t last_counter[MAX_ROUTERS][SYSTEMS + 1];
static unsigned seen_id[MAX_ROUTERS];
static atomic_uint_fast64_t sent_at[LAT_MAX]; /* ns, by frame index; 0 none */
static atomic_uint_fast64_t latency[LAT_MAX]; /* ns, by frame index; 0 none */
static struct router routers[MAX_ROUTERS];
static int nrouters;

static uint64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

/* CRC-16/MCRF4XX as the MAVLink specification defines it, byte by byte. */
static uint16_t crc_add(uint16_t crc, uint8_t b) {
    uint8_t t = b ^ (uint8_t)(crc & 0xff);
    t ^= (uint8_t)(t << 4);
    return (uint16_t)((crc >> 8) ^ ((uint16_t)t << 8) ^ ((uint16_t)t << 3) ^ (t >> 4));
}

static uint16_t frame_crc(const uint8_t *f, int len, uint8_t extra) {
    uint16_t crc = 0xffff;
    for (int i = 1; i < 10 + len; i++) crc = crc_add(crc, f[i]);
    return crc_add(crc, extra);
}

static const struct msg_type *type_of(uint32_t id) {
    for (int i = 0; i < TYPES; i++)
        if (TYPES_[i].id == id) return &TYPES_[i];
    return NULL;
}

/* Frame number `index` of the phase, written at `f`; returns its length. */
static int make_frame(uint8_t *f, uint32_t phase_id, uint32_t index, uint8_t *seqs) {
    uint8_t sys = (uint8_t)(index % SYSTEMS + 1);
    const struct msg_type *t = &TYPES_[(index / SYSTEMS) % TYPES];
    uint32_t counter = (phase_id & 63) << 26 | (index & 0x3ffffff);
    f[0] = 0xFD;
    f[1] = t->len;
    f[2] = 0;
    f[3] = 0;
    f[4] = seqs[sys]++;
    f[5] = sys;
    f[6] = 1;
    f[7] = (uint8_t)t->id;
    f[8] = (uint8_t)(t->id >> 8);
    f[9] = (uint8_t)(t->id >> 16);
    memcpy(f + 10, &counter, 4);
    /* Nonzero filler, last byte too, so no payload would be truncated. */
    for (int i = 4; i < t->len; i++) f[10 + i] = (uint8_t)(0x11 * (i % 15 + 1));
    if (t->id == 0) { /* HEARTBEAT: fixed wing, ArduPilot, armed, active, v3 */
        f[14] = 1, f[15] = 3, f[16] = 0x81, f[17] = 4, f[18] = 3;
    }
    uint16_t crc = frame_crc(f, t->len, t->crc_extra);
    f[10 + t->len] = (uint8_t)crc;
    f[11 + t->len] = (uint8_t)(crc >> 8);
    return 12 + t->len;
}

/* Checks one datagram's frames, counted into `sink`. */
static void check_datagram(int r, const uint8_t *d, int n, uint64_t at) {
    unsigned phase_id = atomic_load(&sink.phase_id) & 63;
    int off = 0;
    while (off < n) {
        const uint8_t *f = d + off;
        if (n - off < 12 || f[0] != 0xFD || f[2] != 0 || n - off < 12 + f[1]) {
            atomic_fetch_add(&sink.bad[r], 1);
            return;
        }
        int len = f[1];
        uint32_t id = f[7] | (uint32_t)f[8] << 8 | (uint32_t)f[9] << 16;
        const struct msg_type *t = type_of(id);
        uint16_t crc = f[10 + len] | (uint16_t)f[11 + len] << 8;
        uint32_t counter = 0;
        if (len >= 4) memcpy(&counter, f + 10, 4);
        if (!t || f[5] < 1 || f[5] > SYSTEMS || len != t->len ||
            crc != frame_crc(f, len, t->crc_extra)) {
            atomic_fetch_add(&sink.bad[r], 1);
        } else if (counter >> 26 != phase_id) {
            atomic_fetch_add(&sink.stale[r], 1);
        } else {
            atomic_fetch_add(&sink.good[r], 1);
            if (seen_id[r] != phase_id) { /* a new slice: order starts again */
                memset(last_counter[r], 0, sizeof last_counter[r]);
                seen_id[r] = phase_id;
            }
            uint32_t *last = &last_counter[r][f[5]];
            if (*last && counter <= *last) atomic_fetch_add(&sink.disorder[r], 1);
            *last = counter;
            uint32_t index = counter & 0x3ffffff;
            uint64_t sent = index < LAT_MAX ? atomic_load(&sent_at[index]) : 0;
            if (atomic_load(&sink.lat_on) && sent) atomic_store(&latency[index], at - sent);
        }
        off += 12 + len;
    }
}

static void *sink_main(void *arg) {
    (void)arg;
    static uint8_t bufs[BATCH][2048];
    struct mmsghdr msgs[BATCH];
    struct iovec iov[BATCH];
    struct pollfd pfd[MAX_ROUTERS];
    for (int i = 0; i < nrouters; i++) pfd[i] = (struct pollfd){routers[i].sink_fd, POLLIN, 0};
    while (!atomic_load(&sink.stop)) {
        if (poll(pfd, (nfds_t)nrouters, 50) <= 0) continue;
        for (int r = 0; r < nrouters; r++) {
            if (!(pfd[r].revents & POLLIN)) continue;
            for (;;) {
                for (int i = 0; i < BATCH; i++) {
                    iov[i] = (struct iovec){bufs[i], sizeof bufs[i]};
                    msgs[i].msg_hdr = (struct msghdr){.msg_iov = &iov[i], .msg_iovlen = 1};
                }
                int got = recvmmsg(routers[r].sink_fd, msgs, BATCH, MSG_DONTWAIT, NULL);
                if (got <= 0) break;
                uint64_t at = now_ns();
                for (int i = 0; i < got; i++) check_datagram(r, bufs[i], (int)msgs[i].msg_len, at);
                if (got < BATCH) break;
            }
        }
    }
    return NULL;
}

/* The drops column of /proc/net/udp for the socket bound to 127.0.0.1:port. */
static uint64_t udp_drops(int port) {
    FILE *f = fopen("/proc/net/udp", "r");
    if (!f) return 0;
    char line[512], want[32];
    snprintf(want, sizeof want, "0100007F:%04X", port);
    uint64_t drops = 0;
    while (fgets(line, sizeof line, f)) {
        if (!strstr(line, want) || strstr(line, want) > line + 20) continue;
        char *tok, *last = NULL, *save = NULL;
        for (tok = strtok_r(line, " \n", &save); tok; tok = strtok_r(NULL, " \n", &save)) last = tok;
        if (last) drops += strtoull(last, NULL, 10);
    }
    fclose(f);
    return drops;
}

/* utime + stime of a process, clock ticks (/proc/PID/stat fields 14, 15). */
static uint64_t stat_ticks(int pid) {
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", pid);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    char *p = strrchr(buf, ')'); /* the name may hold spaces */
    unsigned long ut = 0, st = 0;
    if (!p || sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st) != 2)
        return 0;
    return ut + st;
}

/* Run time of every thread of a process, ns (schedstat's first field). */
static uint64_t sched_ns(int pid) {
    char path[300];
    snprintf(path, sizeof path, "/proc/%d/task", pid);
    DIR *d = opendir(path);
    if (!d) return 0;
    uint64_t sum = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.') continue;
        snprintf(path, sizeof path, "/proc/%d/task/%s/schedstat", pid, e->d_name);
        FILE *f = fopen(path, "r");
        unsigned long long ns = 0;
        if (f && fscanf(f, "%llu", &ns) == 1) sum += ns;
        if (f) fclose(f);
    }
    closedir(d);
    return sum;
}

static void sleep_until(uint64_t t) {
    struct timespec ts = {(time_t)(t / 1000000000u), (long)(t % 1000000000u)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {}
}

/* Sends the phase's load; returns the frames sent. */
static uint64_t send_phase(int fd, const struct phase *p, uint32_t phase_id) {
    static uint8_t bufs[BATCH][MAX_PER_DGRAM * FRAME_MAX];
    struct mmsghdr msgs[BATCH];
    struct iovec iov[BATCH];
    uint8_t seqs[SYSTEMS + 1] = {0};
    uint64_t t0 = now_ns(), end = t0 + (uint64_t)(p->secs * 1e9), index = 0, sent = 0;
    if (p->rate) {
        uint64_t period = 1000000000u / (uint64_t)p->rate;
        for (uint64_t next = t0; next < end; next += period) {
            sleep_until(next);
            int n = make_frame(bufs[0], phase_id, (uint32_t)index, seqs);
            if (p->latency && index < LAT_MAX) atomic_store(&sent_at[index], now_ns());
            if (send(fd, bufs[0], (size_t)n, 0) == n) index++;
        }
        return index;
    }
    while (now_ns() < end && index < 0x3ffffff - BATCH * MAX_PER_DGRAM) {
        for (int i = 0; i < BATCH; i++) {
            int n = 0;
            for (int k = 0; k < p->per_dgram; k++)
                n += make_frame(bufs[i] + n, phase_id, (uint32_t)(index + (uint64_t)(i * p->per_dgram + k)), seqs);
            iov[i] = (struct iovec){bufs[i], (size_t)n};
            msgs[i].msg_hdr = (struct msghdr){.msg_iov = &iov[i], .msg_iovlen = 1};
        }
        /* Counters of datagrams not sent are skipped, never reused. */
        int n = sendmmsg(fd, msgs, BATCH, 0);
        if (n > 0) sent += (uint64_t)n * (uint64_t)p->per_dgram;
        index += BATCH * p->per_dgram;
    }
    return sent;
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Median and p99 of the latencies recorded, microseconds; -1 without. */
static void latency_stats(uint64_t frames, double *p50, double *p99) {
    static uint64_t v[LAT_MAX];
    size_t n = 0;
    for (uint64_t i = 0; i < frames && i < LAT_MAX; i++) {
        uint64_t l = atomic_load(&latency[i]);
        if (l) v[n++] = l;
    }
    *p50 = *p99 = -1;
    if (!n) return;
    qsort(v, n, sizeof v[0], cmp_u64);
    *p50 = (double)v[n / 2] / 1e3;
    *p99 = (double)v[(n * 99) / 100 < n ? (n * 99) / 100 : n - 1] / 1e3;
}

static int udp_socket(int port, int bind_it) {
    int fd = socket(AF_INET, SOCK_DGRAM, 0);
    if (fd < 0) return -1;
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    /* A large sink buffer, so loss is the router's, not the sink's. */
    int size = 16 << 20;
    if (bind_it && setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &size, sizeof size) != 0)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
    if ((bind_it ? bind(fd, (struct sockaddr *)&a, sizeof a) : connect(fd, (struct sockaddr *)&a, sizeof a)) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

/* One slice of a phase for router r, under slice id `phase_id`. */
static void run_slice(int r, const struct phase *ph, int slice, uint32_t phase_id, long hz) {
    struct router *ro = &routers[r];
    int fd = udp_socket(ro->in_port, 0);
    if (fd < 0) { perror("source socket"); exit(1); }
    /* The new slice first: from here on the sink counts a late frame of
     * the last one as stale and reads no table entry for it. */
    atomic_store(&sink.phase_id, phase_id);
    atomic_store(&sink.lat_on, 0);
    for (size_t i = 0; i < LAT_MAX; i++) atomic_store(&sent_at[i], 0), atomic_store(&latency[i], 0);
    atomic_store(&sink.good[r], 0), atomic_store(&sink.bad[r], 0);
    atomic_store(&sink.stale[r], 0), atomic_store(&sink.disorder[r], 0);
    atomic_store(&sink.lat_on, ph->latency);
    uint64_t in0 = udp_drops(ro->in_port), out0 = udp_drops(ro->out_port);
    uint64_t tk0 = stat_ticks(ro->pid), ns0 = sched_ns(ro->pid), t0 = now_ns();
    uint64_t sent = send_phase(fd, ph, phase_id), t_sent = now_ns();
    usleep((useconds_t)(ph->drain * 1e6));
    uint64_t tk1 = stat_ticks(ro->pid), ns1 = sched_ns(ro->pid), t1 = now_ns();
    uint64_t in_drops = udp_drops(ro->in_port) - in0, out_drops = udp_drops(ro->out_port) - out0;
    double p50, p99;
    latency_stats(ph->latency ? sent : 0, &p50, &p99);
    uint64_t lost_in = in_drops * (uint64_t)ph->per_dgram;
    printf("%s %s %d %d %llu %llu %llu %llu %llu %llu %llu %llu %.6f %llu %.3f %.3f %.1f %.1f\n", ro->name,
           ph->name, slice, ph->per_dgram, (unsigned long long)sent,
           (unsigned long long)(sent > lost_in ? sent - lost_in : 0),
           (unsigned long long)atomic_load(&sink.good[r]), (unsigned long long)atomic_load(&sink.bad[r]),
           (unsigned long long)atomic_load(&sink.stale[r]), (unsigned long long)atomic_load(&sink.disorder[r]),
           (unsigned long long)in_drops, (unsigned long long)out_drops,
           (double)(tk1 - tk0) / (double)hz, (unsigned long long)(ns1 - ns0), (double)(t_sent - t0) / 1e9, (double)(t1 - t0) / 1e9,
           p50, p99);
    fflush(stdout);
    close(fd);
}

int main(int argc, char **argv) {
    if (argc < 2 || argc - 1 > MAX_ROUTERS) {
        fprintf(stderr, "usage: %s NAME:PID:IN_PORT:OUT_PORT [...] (at most %d)\n", argv[0], MAX_ROUTERS);
        return 2;
    }
    prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0); /* pacing to the microsecond */
    for (int i = 1; i < argc; i++) {
        struct router *ro = &routers[nrouters++];
        if (sscanf(argv[i], "%31[^:]:%d:%d:%d", ro->name, &ro->pid, &ro->in_port, &ro->out_port) != 4) {
            fprintf(stderr, "bad router spec %s\n", argv[i]);
            return 2;
        }
        ro->sink_fd = udp_socket(ro->out_port, 1);
        if (ro->sink_fd < 0) { perror("sink bind"); return 1; }
    }
    const char *scale_s = getenv("ROUTER_LOAD_SCALE"), *slices_s = getenv("ROUTER_LOAD_SLICES");
    double scale = scale_s ? atof(scale_s) : 1.0;
    int slices = slices_s ? atoi(slices_s) : 6;
    if (slices < 1 || slices > 100) slices = 6;
    long hz = sysconf(_SC_CLK_TCK);
    pthread_t th;
    if (pthread_create(&th, NULL, sink_main, NULL) != 0) return 1;
    printf("router phase slice per_dgram sent read delivered bad stale disorder in_drops out_drops "
           "cpu_stat_s cpu_sched_ns load_s wall_s p50_us p99_us\n");
    uint32_t phase_id = 1;
    for (unsigned p = 0; p < NPHASES; p++) {
        const char *only = getenv("ROUTER_LOAD_ONLY"); /* one phase, for profiles */
        if (only && strcmp(only, PHASES[p].name) != 0) continue;
        struct phase ph = PHASES[p];
        ph.secs *= (scale > 0 && scale <= 10 ? scale : 1.0) / slices;
        for (int k = 0; k < slices; k++)
            for (int r = 0; r < nrouters; r++, phase_id++) run_slice(r, &ph, k, phase_id, hz);
    }
    atomic_store(&sink.stop, 1);
    pthread_join(th, NULL);
    return 0;
}
