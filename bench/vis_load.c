/* bench_vis_load: the visibility server under load on loopback (issue 18, section 4;
 * docs/vis-server.md). N walkers (1.5 m/s) and M drivers (30 m/s) on a generated city each walk
 * their own street path, sending a viewpoint at --rate Hz (30) to one server for --seconds, and
 * take the newest complete set each frame (double-buffered, as a renderer would).
 *
 * The server runs in this process, the clients in a forked child, so that the server's CPU time
 * (getrusage of this process over the timed window) and its memory are its own.
 *
 * Reported:
 *  - latency: viewpoint sent -> first set received that is valid for it (a point set answering
 *    exactly that viewpoint; a cell set whose cell holds the viewpoint, sl_vis_reference_cell),
 *    p50/p99 over every viewpoint that got one; viewpoints that never got one (coalesced away,
 *    or the run ended) counted apart;
 *  - bytes per client per second received; server CPU (% of one core) and memory (the server's
 *    own count per client: the most one client held, and the bound; RSS growth per client);
 *  - frames displaying a set not valid at the client's position at that frame (a point set is
 *    valid only at the viewpoint it answers, so a moving client that does not stall always shows
 *    the previous frame's set: this counts that, it is not an error of the server);
 *  - wrong sets: received sets whose ids differ from the reference's (what the method computes at
 *    that viewpoint), checked after the timed run on --check sets per client (must be 0);
 *  - starved clients: no valid set for more than a second at some point of the run.
 *
 *   bench_vis_load [--city tiny|small|vienna] [--walkers N] [--drivers M] [--method SPEC]
 *                  [--seconds S] [--rate HZ] [--workers W] [--no-reuse] [--check K]
 *                  [--write-paths FILE] [--json]
 * --write-paths FILE writes every client's path as one path file (for `sightline pvs build
 * --along FILE`) and exits. */
#include "bench_common.h"

#include "sightline/gen.h"
#include "sightline/net.h"
#include "sightline/path.h"

#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void die(const char *what, const sl_error *err)
{
    fprintf(stderr, "bench_vis_load: %s: %s\n", what, err ? err->message : "");
    exit(1);
}

typedef struct received {
    uint32_t seq, cell, count;
    uint8_t validity;
    double t;
    uint64_t hash;
} received;

typedef struct client_run {
    uint32_t index;
    bool driver;
    uint16_t port;
    sl_path path;
    uint32_t frames;
    double rate, start;
    double *sent;          /* per frame */
    uint32_t *shown;       /* per frame: 1 + the index in got of the displayed set (0: none) */
    received *got;
    uint32_t got_count;
    uint64_t bytes_in;
    uint64_t connects;
    char error[600];
} client_run;

static uint64_t hash_ids(const uint32_t *ids, uint32_t n)
{
    uint64_t h = 1469598103934665603ull;
    for (uint32_t i = 0; i < n; i++) {
        h ^= ids[i];
        h *= 1099511628211ull;
    }
    return h ^ n;
}

static void *client_main(void *arg)
{
    client_run *r = arg;
    sl_error err;
    sl_vis_client_options co = {.port = r->port, .intrinsics = sl_path_intrinsics(r->path), .reconnect_ms = 50};
    sl_vis_client c;
    if (sl_vis_client_create(&co, &c, &err) != SL_OK) {
        snprintf(r->error, sizeof r->error, "%s", err.message);
        return NULL;
    }
    float speed = r->driver ? 30.0f : 1.5f;
    uint32_t last = 0;
    for (uint32_t f = 0; f < r->frames; f++) {
        double at = r->start + f / r->rate;
        double wait = at - now_s();
        if (wait > 0) {
            struct timespec ts = {(time_t)wait, (long)((wait - floor(wait)) * 1e9)};
            nanosleep(&ts, NULL);
        }
        sl_camera cam = sl_path_camera(r->path, f);
        r->sent[f] = now_s();
        sl_vis_client_send_view(c, &cam, speed, NULL, &err);
        sl_vis_set s;
        sl_vis_client_acquire(c, &s);
        if (s.seq > last) {
            /* every set displayed once; sets replaced before a frame took them are not seen (the
             * client's triple buffer keeps the newest) */
            received *g = &r->got[r->got_count++];
            *g = (received){.seq = s.seq, .cell = s.cell, .count = s.count, .validity = (uint8_t)s.validity,
                            .t = s.received, .hash = hash_ids(s.ids, s.count)};
            last = s.seq;
        }
        r->shown[f] = s.seq ? r->got_count : 0;
    }
    /* the last viewpoints' sets */
    sl_vis_client_wait(c, r->frames, 1000);
    sl_vis_set s;
    sl_vis_client_acquire(c, &s);
    if (s.seq > last)
        r->got[r->got_count++] = (received){.seq = s.seq, .cell = s.cell, .count = s.count,
                                            .validity = (uint8_t)s.validity, .t = s.received,
                                            .hash = hash_ids(s.ids, s.count)};
    sl_vis_client_stats cs;
    sl_vis_client_get_stats(c, &cs);
    r->bytes_in = cs.bytes_in;
    r->connects = cs.connects;
    if (cs.errors)
        snprintf(r->error, sizeof r->error, "%s", cs.last_error);
    sl_vis_client_destroy(c);
    return NULL;
}

typedef struct opts {
    const char *city, *method, *write_paths;
    uint32_t walkers, drivers, workers, check;
    double seconds, rate;
    bool no_reuse, json;
} opts;

static sl_path client_path(sl_scene scene, const opts *o, uint32_t i, uint32_t frames)
{
    bool driver = i >= o->walkers;
    sl_path_options po = sl_path_options_default(driver ? SL_PATH_DRIVE : SL_PATH_WALK);
    po.frames = frames;
    po.fps = (float)o->rate;
    po.speed = driver ? 30.0f : 1.5f;
    po.seed = 1000 + i;
    sl_path p;
    sl_error err;
    if (sl_path_generate(scene, &po, NULL, &p, &err) != SL_OK)
        die("path", &err);
    return p;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The clients (the forked child): run, check, and write the results to fd. */
static void run_clients(sl_scene scene, const opts *o, uint16_t port, int fd)
{
    uint32_t n = o->walkers + o->drivers;
    uint32_t frames = (uint32_t)(o->seconds * o->rate);
    client_run *runs = calloc(n, sizeof *runs);
    pthread_t *th = calloc(n, sizeof *th);
    double start = now_s() + 0.5;
    for (uint32_t i = 0; i < n; i++) {
        client_run *r = &runs[i];
        r->index = i;
        r->driver = i >= o->walkers;
        r->port = port;
        r->path = client_path(scene, o, i, frames);
        r->frames = sl_path_count(r->path);
        r->rate = o->rate;
        /* clients start spread over one frame, as independent viewers would */
        r->start = start + (double)i / n / o->rate;
        r->sent = calloc(r->frames, sizeof *r->sent);
        r->shown = calloc(r->frames, sizeof(uint32_t));
        r->got = calloc((size_t)r->frames + 2, sizeof *r->got);
    }
    /* tell the server when the timed window starts and ends */
    char go = 'g';
    if (write(fd, &go, 1) != 1)
        exit(1);
    for (uint32_t i = 0; i < n; i++)
        pthread_create(&th[i], NULL, client_main, &runs[i]);
    for (uint32_t i = 0; i < n; i++)
        pthread_join(th[i], NULL);
    double end = now_s();
    go = 'e';
    if (write(fd, &go, 1) != 1)
        exit(1);

    /* latency, validity, starvation; then the content check on a sample */
    sl_error err;
    sl_vis_reference ref;
    if (sl_vis_reference_create(scene, o->method, !o->no_reuse, NULL, NULL, &ref, &err) != SL_OK)
        die("reference", &err);
    uint32_t objects = sl_scene_object_count(scene);
    uint32_t *ids = malloc(((size_t)objects + 1) * sizeof *ids);
    double *lat = malloc(((size_t)n * frames + 1) * sizeof *lat);
    size_t nlat = 0;
    uint64_t unanswered = 0, invalid_frames = 0, total_frames = 0, checked = 0, wrong = 0, bytes = 0, sets = 0;
    uint32_t starved = 0, errors = 0;
    char first_error[700] = "";
    for (uint32_t i = 0; i < n; i++) {
        client_run *r = &runs[i];
        if (r->error[0]) {
            errors++;
            if (!first_error[0])
                snprintf(first_error, sizeof first_error, "client %u: %s", i, r->error);
        }
        bytes += r->bytes_in;
        sets += r->got_count;
        uint32_t *cell_of = malloc(((size_t)r->frames + 1) * sizeof *cell_of);
        for (uint32_t f = 0; f < r->frames; f++) {
            sl_camera cam = sl_path_camera(r->path, f);
            cell_of[f] = sl_vis_reference_cell(ref, &cam);
        }
        /* first valid set for each viewpoint f (seq f+1): sets are received in seq order */
        uint32_t g = 0;
        double last_valid = start;
        bool starving = false;
        for (uint32_t f = 0; f < r->frames; f++) {
            while (g < r->got_count && r->got[g].seq < f + 1)
                g++;
            double t = -1;
            for (uint32_t k = g; k < r->got_count; k++) {
                const received *s = &r->got[k];
                if (s->validity == SL_VIS_POINT ? s->seq == f + 1 : s->cell == cell_of[f]) {
                    t = s->t;
                    break;
                }
                if (s->validity == SL_VIS_POINT && s->seq > f + 1)
                    break;
            }
            /* a cell set already displayed when the viewpoint was sent, and valid there: 0 */
            uint32_t shown = r->shown[f];
            if (t < 0 && f > 0 && shown) {
                const received *s = &r->got[shown - 1];
                if (s->validity == SL_VIS_CELL && s->cell == cell_of[f] && s->t <= r->sent[f])
                    t = r->sent[f];
            }
            if (t >= 0) {
                double l = t - r->sent[f];
                lat[nlat++] = 1e3 * (l > 0 ? l : 0);
                if (t - last_valid > 1.0)
                    starving = true;
                if (t > last_valid)
                    last_valid = t;
            } else {
                unanswered++;
            }
            /* the set displayed at frame f: valid at f's position? */
            total_frames++;
            if (!shown) {
                invalid_frames++;
            } else {
                const received *s = &r->got[shown - 1];
                if (!(s->validity == SL_VIS_POINT ? s->seq == f + 1 : s->cell == cell_of[f]))
                    invalid_frames++;
            }
        }
        if (end - last_valid > 1.0 + 1.0 / o->rate)
            starving = true;
        starved += starving;
        /* content: a sample of the received sets against the reference */
        for (uint32_t k = 0; k < o->check && r->got_count; k++) {
            const received *s = &r->got[(size_t)k * r->got_count / o->check];
            if (k && s == &r->got[(size_t)(k - 1) * r->got_count / o->check])
                continue;
            sl_camera cam = sl_path_camera(r->path, s->seq - 1);
            uint32_t count, cell;
            sl_vis_validity v;
            if (sl_vis_reference_compute(ref, &cam, ids, objects, &count, &v, &cell, &err) != SL_OK)
                die("reference", &err);
            checked++;
            if (v != s->validity || cell != s->cell || count != s->count || hash_ids(ids, count) != s->hash)
                wrong++;
        }
        free(cell_of);
    }
    qsort(lat, nlat, sizeof *lat, cmp_double);
    double secs = end - start;
    FILE *out = fdopen(fd, "w");
    fprintf(out, "%zu %.4f %.4f %.4f %llu %llu %llu %llu %llu %.1f %u %u %llu\n%s\n", nlat,
            nlat ? lat[nlat / 2] : 0.0, nlat ? lat[(size_t)(0.99 * (double)(nlat - 1))] : 0.0,
            nlat ? lat[nlat - 1] : 0.0, (unsigned long long)unanswered, (unsigned long long)invalid_frames,
            (unsigned long long)total_frames, (unsigned long long)checked, (unsigned long long)wrong,
            (double)bytes / n / secs, starved, errors, (unsigned long long)sets, first_error);
    fclose(out);
    sl_vis_reference_destroy(ref);
    exit(0);
}

static uint64_t rss_bytes(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return 0;
    char line[256];
    uint64_t kb = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "VmRSS:", 6))
            kb = strtoull(line + 6, NULL, 10);
    fclose(f);
    return kb * 1024;
}

static double cpu_s(void)
{
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_utime.tv_sec + 1e-6 * u.ru_utime.tv_usec + (double)u.ru_stime.tv_sec +
           1e-6 * u.ru_stime.tv_usec;
}

int main(int argc, char **argv)
{
    opts o = {.city = "small", .method = "cullmap", .walkers = 15, .drivers = 5, .workers = 2, .check = 10,
              .seconds = 10, .rate = 30};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--json")) {
            o.json = true;
        } else if (!strcmp(a, "--no-reuse")) {
            o.no_reuse = true;
        } else if (v && !strcmp(a, "--city")) {
            o.city = v, i++;
        } else if (v && !strcmp(a, "--method")) {
            o.method = v, i++;
        } else if (v && !strcmp(a, "--write-paths")) {
            o.write_paths = v, i++;
        } else if (v && !strcmp(a, "--walkers")) {
            o.walkers = (uint32_t)strtoul(v, NULL, 10), i++;
        } else if (v && !strcmp(a, "--drivers")) {
            o.drivers = (uint32_t)strtoul(v, NULL, 10), i++;
        } else if (v && !strcmp(a, "--workers")) {
            o.workers = (uint32_t)strtoul(v, NULL, 10), i++;
        } else if (v && !strcmp(a, "--check")) {
            o.check = (uint32_t)strtoul(v, NULL, 10), i++;
        } else if (v && !strcmp(a, "--seconds")) {
            o.seconds = strtod(v, NULL), i++;
        } else if (v && !strcmp(a, "--rate")) {
            o.rate = strtod(v, NULL), i++;
        } else {
            fprintf(stderr, "usage: bench_vis_load [--city tiny|small|vienna] [--walkers N] [--drivers M] "
                            "[--method SPEC] [--seconds S] [--rate HZ] [--workers W] [--no-reuse] [--check K] "
                            "[--write-paths FILE] [--json]\n");
            return 2;
        }
    }
    uint32_t n = o.walkers + o.drivers;
    if (n == 0 || n > 2000 || !(o.seconds > 0 && o.seconds <= 600) || !(o.rate >= 1 && o.rate <= 240) ||
        o.workers < 1 || o.workers > 64) {
        fprintf(stderr, "bench_vis_load: 1..2000 clients, --seconds (0, 600], --rate 1..240, --workers 1..64\n");
        return 2;
    }
    sl_error err;
    sl_city_preset preset;
    if (sl_city_preset_from_name(o.city, &preset, &err) != SL_OK)
        die("--city", &err);
    sl_city_options co = sl_city_defaults(preset);
    sl_scene scene;
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK)
        die("city", &err);
    uint32_t frames = (uint32_t)(o.seconds * o.rate);
    if (o.write_paths) {
        sl_path all;
        sl_path first = client_path(scene, &o, 0, frames);
        sl_camera in = sl_path_intrinsics(first);
        if (sl_path_create(&in, NULL, &all, &err) != SL_OK)
            die("path", &err);
        float t = 0;
        for (uint32_t i = 0; i < n; i++) {
            sl_path p = i ? client_path(scene, &o, i, frames) : first;
            for (uint32_t f = 0; f < sl_path_count(p); f++) {
                sl_pose pose = sl_path_poses(p)[f];
                pose.time = t;
                t += 1.0f / (float)o.rate;
                sl_path_append(all, &pose, &err);
            }
            sl_path_destroy(p);
        }
        if (sl_path_save(all, o.write_paths, &err) != SL_OK)
            die(o.write_paths, &err);
        printf("%s: %u clients' paths, %u poses\n", o.write_paths, n, sl_path_count(all));
        sl_path_destroy(all);
        sl_scene_destroy(scene);
        return 0;
    }
    int pipe_port[2], pipe_res[2];
    if (pipe(pipe_port) || pipe(pipe_res))
        die("pipe", NULL);
    pid_t child = fork();
    if (child < 0)
        die("fork", NULL);
    if (child == 0) {
        close(pipe_port[1]);
        close(pipe_res[0]);
        uint16_t port;
        if (read(pipe_port[0], &port, sizeof port) != (ssize_t)sizeof port)
            exit(1);
        run_clients(scene, &o, port, pipe_res[1]);
    }
    close(pipe_port[0]);
    close(pipe_res[1]);
    sl_vis_server_options so = {.method = o.method, .workers = o.workers, .no_reuse = o.no_reuse,
                                .max_clients = n + 16};
    sl_vis_server s;
    if (sl_vis_server_create(scene, &so, &s, &err) != SL_OK) {
        kill(child, SIGKILL);
        die("server", &err);
    }
    uint64_t rss1 = rss_bytes();
    uint16_t port = sl_vis_server_port(s);
    if (write(pipe_port[1], &port, sizeof port) != (ssize_t)sizeof port)
        die("pipe", NULL);
    char c;
    if (read(pipe_res[0], &c, 1) != 1)
        die("the clients ended early", NULL);
    double cpu0 = cpu_s(), t0 = now_s();
    uint64_t rss_peak = rss1;
    sl_vis_server_stats st;
    for (;;) {
        /* sample the server's memory while the clients run */
        fd_set rd;
        FD_ZERO(&rd);
        FD_SET(pipe_res[0], &rd);
        struct timeval tv = {0, 200000};
        if (select(pipe_res[0] + 1, &rd, NULL, NULL, &tv) > 0)
            break;
        uint64_t r = rss_bytes();
        if (r > rss_peak)
            rss_peak = r;
    }
    if (read(pipe_res[0], &c, 1) != 1)
        die("the clients ended early", NULL);
    double cpu1 = cpu_s(), t1 = now_s();
    sl_vis_server_get_stats(s, &st);
    FILE *res = fdopen(pipe_res[0], "r");
    size_t nlat;
    double p50, p99, pmax, bps;
    unsigned long long unanswered, invalid, total, checked, wrong, sets;
    unsigned starved, errors;
    char first_error[400] = "";
    int got = fscanf(res, "%zu %lf %lf %lf %llu %llu %llu %llu %llu %lf %u %u %llu\n", &nlat, &p50, &p99, &pmax,
                     &unanswered, &invalid, &total, &checked, &wrong, &bps, &starved, &errors, &sets);
    if (got != 13)
        die("no results from the clients", NULL);
    if (!fgets(first_error, sizeof first_error, res))
        first_error[0] = 0;
    first_error[strcspn(first_error, "\n")] = 0;
    int status;
    waitpid(child, &status, 0);
    sl_vis_server_destroy(s);
    double cpu_pct = 100.0 * (cpu1 - cpu0) / (t1 - t0);
    char machine[400];
    bench_machine(machine, sizeof machine);
    if (o.json) {
        printf("{\"city\":\"%s\",\"method\":\"%s\",\"reuse\":%s,\"walkers\":%u,\"drivers\":%u,\"rate_hz\":%.0f,"
               "\"seconds\":%.1f,\"workers\":%u,\"latency_p50_ms\":%.3f,\"latency_p99_ms\":%.3f,\"latency_max_ms\":%.3f,"
               "\"viewpoints_answered\":%zu,\"viewpoints_unanswered\":%llu,\"bytes_per_client_s\":%.1f,"
               "\"server_cpu_pct\":%.1f,\"client_bytes_max\":%llu,\"client_bytes_bound\":%llu,"
               "\"rss_per_client\":%.0f,\"frames\":%llu,\"frames_invalid_set\":%llu,\"sets_checked\":%llu,"
               "\"wrong_sets\":%llu,\"starved\":%u,\"client_errors\":%u,\"culls\":%llu,\"cache_hits\":%llu,"
               "\"views_coalesced\":%llu,\"sets_dropped\":%llu,\"machine\":\"%s\"}\n",
               o.city, o.method, o.no_reuse ? "false" : "true", o.walkers, o.drivers, o.rate, o.seconds, o.workers,
               p50, p99, pmax, nlat, unanswered, bps, cpu_pct, (unsigned long long)st.client_bytes_max,
               (unsigned long long)st.client_bytes_bound, (double)(rss_peak - rss1) / n, total, invalid, checked,
               wrong, starved, errors, (unsigned long long)st.culls, (unsigned long long)st.cache_hits,
               (unsigned long long)st.views_coalesced, (unsigned long long)st.sets_dropped, machine);
    } else {
        printf("visibility server under load: city %s, method %s%s, %u walkers (1.5 m/s) + %u drivers (30 m/s) at "
               "%.0f Hz for %.0f s, %u workers\n", o.city, o.method, o.no_reuse ? " (no reuse)" : "", o.walkers,
               o.drivers, o.rate, o.seconds, o.workers);
        printf("  machine: %s\n", machine);
        printf("  latency viewpoint -> first valid set: p50 %.2f ms, p99 %.2f ms, max %.2f ms (%zu viewpoints; "
               "%llu never got one: coalesced or the run ended)\n", p50, p99, pmax, nlat, unanswered);
        printf("  %.0f bytes per client per second; server CPU %.0f%% of one core; %llu sets computed, %llu from "
               "the cache, %llu viewpoints coalesced, %llu sets dropped\n", bps, cpu_pct,
               (unsigned long long)st.culls, (unsigned long long)st.cache_hits,
               (unsigned long long)st.views_coalesced, (unsigned long long)st.sets_dropped);
        printf("  memory per client: at most %llu B held (bound %llu B); server RSS growth %.0f B per client\n",
               (unsigned long long)st.client_bytes_max, (unsigned long long)st.client_bytes_bound,
               (double)(rss_peak - rss1) / n);
        printf("  frames displaying a set not valid at the client's position: %llu of %llu\n", invalid, total);
        printf("  wrong sets (ids differ from the method's at that viewpoint): %llu of %llu checked; starved "
               "clients: %u; client errors: %u%s%s\n", wrong, checked, starved, errors, first_error[0] ? ": " : "",
               first_error);
    }
    sl_scene_destroy(scene);
    return wrong || errors ? 1 : 0;
}
