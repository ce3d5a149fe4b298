/* `sightline vis-server` and `sightline vis-client`: the network visibility server and a client
 * that walks a path through it (include/sightline/net.h; docs/vis-server.md, docs/protocol.md). */
#include "cli.h"
#include "tool.h"

#include "sightline/path.h"
#include "sightline/pvs.h"

#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#ifdef SL_HAVE_NET
#include "sightline/net.h"
#endif

static void server_usage(FILE *out)
{
    fprintf(out,
            "usage: sightline vis-server SCENE --method SPEC --port N [options]\n\n"
            "Serve visible sets over TCP: clients send viewpoints, the server answers the ids of the\n"
            "objects the method finds visible there (docs/vis-server.md, docs/protocol.md). It runs\n"
            "until SIGINT or SIGTERM (or --duration), then prints its statistics.\n\n"
            "  SCENE              a .slscene, a model file, or city:PRESET[:SEED]\n"
            "  --method SPEC      NAME[:OPTIONS]: cullmap, dhorizon, pvs:file=X.slpvs ... (sightline methods)\n"
            "  --host ADDR        IPv4 or IPv6 address to listen on (default 127.0.0.1)\n"
            "  --port N           TCP port; 0: a free one (see --port-file)\n"
            "  --port-file FILE   write the port listened on to FILE once listening\n"
            "  --max-clients N    connections at once (default 256)\n"
            "  --workers N        culling threads (default 2)\n"
            "  --rate HZ          most viewpoints a second per client (default 240)\n"
            "  --queue N          unsent sets kept per client, older dropped for newer (default 1)\n"
            "  --max-pixels N     largest width x height a client may cull at (default 8294400, 4K)\n"
            "  --no-reuse         never answer from a cached view-cell set (pvs)\n"
            "  --cache-mb N       size of the view-cell set cache (default 64)\n"
            "  --duration S       stop after S seconds (default: until a signal)\n"
            "  --json             the final statistics as JSON\n"
            "  --quiet            no line when listening\n"
            "  --help             this text\n");
}

static void client_usage(FILE *out)
{
    fprintf(out,
            "usage: sightline vis-client [SCENE] --port N (--path FILE | --walk N | --drive N) [options]\n\n"
            "Walk a camera path through a visibility server: send each viewpoint, take the newest\n"
            "complete set (double-buffered), and with --check compare every displayed set with what\n"
            "the same method computes here at that viewpoint (docs/vis-server.md).\n\n"
            "  SCENE              the server's scene (needed by --walk, --drive and --check)\n"
            "  --host ADDR        server address (default 127.0.0.1)\n"
            "  --port N           server port\n"
            "  --path FILE        a camera path file (docs/paths.md)\n"
            "  --walk N           a generated street walk of N frames (at --speed, default 1.5 m/s)\n"
            "  --drive N          a generated drive of N frames (default 30 m/s)\n"
            "  --speed M          walk or drive speed in m/s\n"
            "  --seed N           path seed (default 1)\n"
            "  --rate HZ          viewpoints a second (default 30, --stall too; 0: as fast as sets come\n"
            "                     with --stall); never above the server's max_rate_hz\n"
            "  --stall            wait for each viewpoint's set before the next (always a valid set)\n"
            "  --check            compare each displayed set with the local method's; count sets\n"
            "                     displayed at a viewpoint they do not hold for\n"
            "  --method SPEC      the method to check with (default: the server's)\n"
            "  --timeout S        seconds to wait for a set or the server (default 10)\n"
            "  --json             the report as JSON\n"
            "  --help             this text\n\n"
            "Exit status 0; 1 when a displayed set differs from the local method's (--check), a\n"
            "viewpoint got no set within --timeout (--stall), no set came at all, --check had\n"
            "nothing to check, or a viewpoint could not be sent (the frame and the reason are\n"
            "named); 2 for a usage error. A connection ended by an error (a refusal by the\n"
            "server, with its text, or a bad message from it) is reported on stderr; the client\n"
            "reconnects after each.\n");
}

#ifndef SL_HAVE_NET
int sl_cmd_vis_server(int argc, char **argv)
{
    if (argc > 1 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        server_usage(stdout);
        return 0;
    }
    cli_error("vis-server", "this sightline was built without the network layer (SL_NET: libuv, libuv1-dev)");
    return 2;
}
int sl_cmd_vis_client(int argc, char **argv)
{
    if (argc > 1 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        client_usage(stdout);
        return 0;
    }
    cli_error("vis-client", "this sightline was built without the network layer (SL_NET: libuv, libuv1-dev)");
    return 2;
}
#else

static volatile sig_atomic_t g_stop;
static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static bool parse_port(cli_args *a, const char *name, const char *v, uint32_t *port)
{
    if (!cli_parse_u32(a, name, v, port))
        return false;
    if (*port > 65535) {
        cli_error(a->cmd, "--%s %u: a port is 0..65535", name, *port);
        a->error = true;
        return false;
    }
    return true;
}

int sl_cmd_vis_server(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_common com = {0};
    const char *name, *val, *method = NULL, *host = NULL, *port_file = NULL;
    uint32_t port = UINT32_MAX, max_clients = 0, workers = 0, rate = 0, queue = 0, cache_mb = 0, duration = 0,
             max_pixels = 0;
    bool no_reuse = false;
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_JSON | CLI_QUIET, &com)) {
        } else if (!strcmp(name, "method")) {
            method = cli_value(&a, name, val);
        } else if (!strcmp(name, "host")) {
            host = cli_value(&a, name, val);
        } else if (!strcmp(name, "port")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                parse_port(&a, name, v, &port);
        } else if (!strcmp(name, "port-file")) {
            port_file = cli_value(&a, name, val);
        } else if (!strcmp(name, "max-clients") || !strcmp(name, "workers") || !strcmp(name, "rate") ||
                   !strcmp(name, "queue") || !strcmp(name, "cache-mb") || !strcmp(name, "duration") ||
                   !strcmp(name, "max-pixels")) {
            const char *v = cli_value(&a, name, val);
            uint32_t *dst = !strcmp(name, "max-clients") ? &max_clients
                            : !strcmp(name, "workers")   ? &workers
                            : !strcmp(name, "rate")      ? &rate
                            : !strcmp(name, "queue")     ? &queue
                            : !strcmp(name, "max-pixels") ? &max_pixels
                            : !strcmp(name, "cache-mb")  ? &cache_mb
                                                         : &duration;
            if (v && cli_parse_u32(&a, name, v, dst) && *dst == 0 && strcmp(name, "duration") != 0) {
                cli_error(a.cmd, "--%s 0: must be at least 1", name);
                a.error = true;
            }
        } else if (!strcmp(name, "no-reuse")) {
            no_reuse = true;
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, server_usage);
    if (parsed >= 0)
        return parsed;
    if (!com.input || !method || port == UINT32_MAX) {
        cli_error(a.cmd, "needs SCENE, --method SPEC and --port N (see sightline vis-server --help)");
        return 2;
    }
    if (cache_mb > 1u << 20) {
        cli_error(a.cmd, "--cache-mb %u: at most 1048576", cache_mb);
        return 2;
    }
    /* the library's limits (net.h), named as options */
    const struct {
        const char *name;
        uint32_t value, max;
    } limits[] = {{"max-clients", max_clients, SL_VIS_MAX_CLIENTS}, {"rate", rate, SL_VIS_MAX_RATE_HZ},
                  {"queue", queue, SL_VIS_MAX_QUEUE_SETS}, {"max-pixels", max_pixels, SL_VIS_MAX_PIXELS}};
    for (size_t i = 0; i < sizeof limits / sizeof limits[0]; i++)
        if (limits[i].value > limits[i].max) {
            cli_error(a.cmd, "--%s %u: at most %u", limits[i].name, limits[i].value, limits[i].max);
            return 2;
        }
    sl_error err;
    sl_scene scene = NULL;
    char label[128];
    if (cli_open_scene(com.input, NULL, NULL, NULL, &scene, label, sizeof label, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_vis_server_options o = {.method = method, .host = host, .port = (uint16_t)port, .max_clients = max_clients,
                               .workers = workers, .max_rate_hz = rate, .queue_sets = queue, .no_reuse = no_reuse,
                               .cache_bytes = (uint64_t)cache_mb << 20,
                               .max_pixels = max_pixels};
    sl_vis_server s = NULL;
    if (sl_vis_server_create(scene, &o, &s, &err) != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    /* before the port file: opening a FIFO blocks until its reader comes, and a signal meanwhile
     * interrupts the open (an error, exit 1) instead of killing the server without a word */
    struct sigaction sa = {.sa_handler = on_signal};
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    if (port_file) {
        sl_output out;
        if (sl_output_open(port_file, NULL, &out, &err) != SL_OK) {
            sl_vis_server_destroy(s);
            sl_scene_destroy(scene);
            return cli_fail(a.cmd, &err);
        }
        fprintf(sl_output_stream(out), "%u\n", sl_vis_server_port(s));
        if (sl_output_commit(out, &err) != SL_OK) {
            sl_vis_server_destroy(s);
            sl_scene_destroy(scene);
            return cli_fail(a.cmd, &err);
        }
    }
    if (!com.quiet && !com.json)
        printf("vis-server: %s, method %s, listening on %s port %u\n", label, method, host ? host : "127.0.0.1",
               sl_vis_server_port(s));
    fflush(stdout);
    double t0 = tool_now();
    while (!g_stop && (duration == 0 || tool_now() - t0 < duration)) {
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    sl_vis_server_stats st;
    sl_vis_server_get_stats(s, &st);
    sl_vis_server_destroy(s);
    sl_scene_destroy(scene);
    double secs = tool_now() - t0;
    if (com.json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "scene", label);
        cli_json_string(&j, "method", method);
        cli_json_double(&j, "seconds", secs);
        cli_json_uint(&j, "clients_total", st.clients_total);
        cli_json_uint(&j, "clients_refused", st.clients_refused);
        cli_json_uint(&j, "views", st.views);
        cli_json_uint(&j, "views_coalesced", st.views_coalesced);
        cli_json_uint(&j, "sets_sent", st.sets_sent);
        cli_json_uint(&j, "sets_dropped", st.sets_dropped);
        cli_json_uint(&j, "culls", st.culls);
        cli_json_uint(&j, "cache_hits", st.cache_hits);
        cli_json_uint(&j, "cache_misses", st.cache_misses);
        cli_json_uint(&j, "bytes_in", st.bytes_in);
        cli_json_uint(&j, "bytes_out", st.bytes_out);
        cli_json_uint(&j, "protocol_errors", st.protocol_errors);
        cli_json_uint(&j, "rate_limited", st.rate_limited);
        cli_json_uint(&j, "client_bytes_max", st.client_bytes_max);
        cli_json_uint(&j, "client_bytes_bound", st.client_bytes_bound);
        cli_json_double(&j, "cull_ms_total", st.cull_ms_total);
        cli_json_end(&j);
    } else {
        printf("vis-server: %.1f s, %llu clients (%llu refused), %llu viewpoints (%llu coalesced), %llu sets sent "
               "(%llu dropped for slow readers), %llu computed, cache %llu hits / %llu misses, %llu bytes out, "
               "%llu protocol errors, %llu rate-limited, client memory max %llu B (bound %llu B)\n",
               secs, (unsigned long long)st.clients_total, (unsigned long long)st.clients_refused,
               (unsigned long long)st.views, (unsigned long long)st.views_coalesced,
               (unsigned long long)st.sets_sent, (unsigned long long)st.sets_dropped, (unsigned long long)st.culls,
               (unsigned long long)st.cache_hits, (unsigned long long)st.cache_misses,
               (unsigned long long)st.bytes_out, (unsigned long long)st.protocol_errors,
               (unsigned long long)st.rate_limited, (unsigned long long)st.client_bytes_max,
               (unsigned long long)st.client_bytes_bound);
    }
    return 0;
}

static double mono_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

static bool subset(const uint32_t *a, uint32_t na, const uint32_t *b, uint32_t nb)
{
    uint32_t j = 0;
    for (uint32_t i = 0; i < na; i++) {
        while (j < nb && b[j] < a[i])
            j++;
        if (j >= nb || b[j] != a[i])
            return false;
    }
    return true;
}

int sl_cmd_vis_client(int argc, char **argv)
{
    cli_args a;
    cli_args_init(&a, argc, argv);
    cli_common com = {0};
    const char *name, *val, *host = NULL, *path_file = NULL, *method = NULL;
    uint32_t port = UINT32_MAX, walk_frames = 0, drive_frames = 0, rate = 30, timeout = 10;
    uint64_t seed = 1;
    float speed = 0;
    bool stall = false, check = false;
    while (cli_next(&a, &name, &val)) {
        if (cli_common_option(&a, name, val, CLI_INPUT | CLI_JSON, &com)) {
        } else if (!strcmp(name, "host")) {
            host = cli_value(&a, name, val);
        } else if (!strcmp(name, "port")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                parse_port(&a, name, v, &port);
        } else if (!strcmp(name, "path")) {
            path_file = cli_value(&a, name, val);
        } else if (!strcmp(name, "method")) {
            method = cli_value(&a, name, val);
        } else if (!strcmp(name, "walk") || !strcmp(name, "drive") || !strcmp(name, "rate") ||
                   !strcmp(name, "timeout")) {
            const char *v = cli_value(&a, name, val);
            uint32_t *dst = !strcmp(name, "walk") ? &walk_frames : !strcmp(name, "drive") ? &drive_frames
                            : !strcmp(name, "rate") ? &rate : &timeout;
            if (v)
                cli_parse_u32(&a, name, v, dst);
        } else if (!strcmp(name, "speed")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_float(&a, name, v, &speed);
        } else if (!strcmp(name, "seed")) {
            const char *v = cli_value(&a, name, val);
            if (v)
                cli_parse_u64(&a, name, v, &seed);
        } else if (!strcmp(name, "stall")) {
            stall = true;
        } else if (!strcmp(name, "check")) {
            check = true;
        } else {
            cli_unknown(&a, name);
        }
    }
    int parsed = cli_parse_done(&a, &com, client_usage);
    if (parsed >= 0)
        return parsed;
    if (port == UINT32_MAX || port == 0) {
        cli_error(a.cmd, "needs --port N (1..65535)");
        return 2;
    }
    if ((path_file != NULL) + (walk_frames > 0) + (drive_frames > 0) != 1) {
        cli_error(a.cmd, "needs exactly one of --path FILE, --walk N, --drive N");
        return 2;
    }
    if ((walk_frames || drive_frames || check) && !com.input) {
        cli_error(a.cmd, "--walk, --drive and --check need the SCENE");
        return 2;
    }
    /* each limit named with the value given */
    char bad[96] = "";
    if (rate > 1000 || (rate == 0 && !stall))
        snprintf(bad, sizeof bad, "--rate %u: 1..1000 (0 only with --stall)", rate);
    else if (timeout < 1 || timeout > 3600)
        snprintf(bad, sizeof bad, "--timeout %u: 1..3600 seconds", timeout);
    else if (walk_frames > 1000000 || drive_frames > 1000000)
        snprintf(bad, sizeof bad, "--%s %u: at most 1000000 frames", walk_frames ? "walk" : "drive",
                 walk_frames ? walk_frames : drive_frames);
    else if (!(speed >= 0 && speed <= 1000))
        snprintf(bad, sizeof bad, "--speed %g: 0..1000 m/s", (double)speed);
    if (bad[0]) {
        cli_error(a.cmd, "%s", bad);
        return 2;
    }
    sl_error err;
    sl_scene scene = NULL;
    char label[128] = "";
    if (com.input && cli_open_scene(com.input, NULL, NULL, NULL, &scene, label, sizeof label, &err) != SL_OK)
        return cli_fail(a.cmd, &err);
    sl_path path = NULL;
    sl_status st;
    if (path_file) {
        st = sl_path_load(path_file, NULL, &path, &err);
    } else {
        sl_path_options po = sl_path_options_default(walk_frames ? SL_PATH_WALK : SL_PATH_DRIVE);
        po.frames = walk_frames ? walk_frames : drive_frames;
        po.speed = speed > 0 ? speed : walk_frames ? 1.5f : 30.0f;
        po.fps = rate ? (float)rate : 30.0f;
        po.seed = seed;
        st = sl_path_generate(scene, &po, NULL, &path, &err);
    }
    if (st != SL_OK) {
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    sl_path_stats ps;
    sl_path_get_stats(path, &ps);
    sl_vis_client_options co = {.host = host, .port = (uint16_t)port, .intrinsics = sl_path_intrinsics(path),
                                .object_count = scene ? sl_scene_object_count(scene) : 0};
    sl_vis_client c = NULL;
    if (sl_vis_client_create(&co, &c, &err) != SL_OK) {
        sl_path_destroy(path);
        sl_scene_destroy(scene);
        return cli_fail(a.cmd, &err);
    }
    int rc = 0;
    sl_vis_reference ref = NULL;
    uint32_t n = scene ? sl_scene_object_count(scene) : 0;
    uint32_t *ids = NULL, *pt = NULL;
    sl_vis_client_stats cs;
    /* the server's welcome first: its method and scene */
    double t0 = tool_now();
    for (;;) {
        sl_vis_client_get_stats(c, &cs);
        if (cs.object_count || cs.connected || tool_now() - t0 > timeout)
            break;
        struct timespec ts = {0, 5 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    if (!cs.connected) {
        const char *h = host ? host : "127.0.0.1";
        if (cs.errors)
            cli_error(a.cmd, "could not start with the server at %s port %u within %u s (%llu tries): %s", h, port,
                      timeout, (unsigned long long)cs.errors, cs.last_error);
        else if (cs.connects)
            cli_error(a.cmd, "the server at %s port %u did not welcome the client within %u s (%llu connections)", h,
                      port, timeout, (unsigned long long)cs.connects);
        else
            cli_error(a.cmd, "no server at %s port %u within %u s%s%s", h, port, timeout,
                      cs.last_error[0] ? ": " : "", cs.last_error);
        rc = 1;
        goto done;
    }
    if (check) {
        if (cs.object_count != n || cs.scene_key != sl_pvs_scene_key(scene)) {
            cli_error(a.cmd, "--check: the server's scene (%u objects, key %016llx) is not %s (%u objects, key %016llx)",
                      cs.object_count, (unsigned long long)cs.scene_key, label, n,
                      (unsigned long long)sl_pvs_scene_key(scene));
            rc = 1;
            goto done;
        }
        if (sl_vis_reference_create(scene, method ? method : cs.method, cs.regions, NULL, NULL, &ref, &err) != SL_OK) {
            rc = cli_fail(a.cmd, &err);
            goto done;
        }
        ids = tool_alloc(NULL, ((size_t)n + 1) * sizeof *ids);
        pt = tool_alloc(NULL, ((size_t)n + 1) * sizeof *pt);
    }
    uint32_t frames = sl_path_count(path);
    double *lat = tool_alloc(NULL, ((size_t)frames + 1) * sizeof *lat);
    double *sent = tool_alloc(NULL, ((size_t)frames + 1) * sizeof *sent);
    uint32_t nlat = 0, checked = 0, mismatches = 0, invalid = 0, timeouts = 0, displayed = 0;
    uint32_t first_seq = 0, last_seen = 0, views_sent = 0;
    char first_problem[300] = "";
    double pace = rate;
    if (cs.max_rate_hz && (pace == 0 || pace > cs.max_rate_hz))
        pace = cs.max_rate_hz;
    double start = tool_now();
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = sl_path_camera(path, f);
        uint32_t seq;
        float v = (float)(ps.speed_mean > 0 ? ps.speed_mean : 0);
        if (sl_vis_client_send_view(c, &cam, v, &seq, &err) != SL_OK) {
            snprintf(first_problem, sizeof first_problem, "frame %u: %.250s", f, err.message);
            rc = 1;
            break;
        }
        views_sent++;
        if (f == 0)
            first_seq = seq;
        sent[f] = mono_now();
        if (stall) {
            if (!sl_vis_client_wait(c, seq, timeout * 1000u)) {
                timeouts++;
                if (!first_problem[0])
                    snprintf(first_problem, sizeof first_problem, "frame %u: no set within %u s", f, timeout);
            }
        }
        /* --rate, and never faster than the server takes (its WELCOME's max_rate_hz), with
         * --stall too: as fast as sets come is still at most that */
        if (pace > 0) {
            double next = start + (double)(f + 1) / pace;
            double wait = next - tool_now();
            if (wait > 0) {
                struct timespec ts = {(time_t)wait, (long)((wait - floor(wait)) * 1e9)};
                nanosleep(&ts, NULL);
            }
        }
        sl_vis_set set;
        if (sl_vis_client_acquire(c, &set) && set.seq >= first_seq) {
            displayed++;
            uint32_t sf = set.seq - first_seq;
            if (set.seq > last_seen && sf < frames) {
                /* viewpoint sent -> its set completely received (both on the monotonic clock) */
                lat[nlat++] = 1e3 * (set.received - sent[sf]);
                last_seen = set.seq;
            }
            if (ref && sf < frames) {
                sl_camera at = sl_path_camera(path, sf);
                uint32_t count, cell;
                sl_vis_validity validity;
                checked++;
                if (sl_vis_reference_compute(ref, &at, ids, n, &count, &validity, &cell, &err) != SL_OK) {
                    rc = cli_fail(a.cmd, &err);
                    break;
                }
                bool same = validity == set.validity && cell == set.cell && count == set.count &&
                            memcmp(ids, set.ids, (size_t)count * sizeof *ids) == 0;
                bool holds = true;
                if (set.validity == SL_VIS_CELL) {
                    uint32_t pc;
                    sl_vis_reference_point(ref, &at, pt, n, &pc, &err);
                    holds = subset(pt, pc, set.ids, set.count);
                }
                if (!same || !holds) {
                    mismatches++;
                    if (!first_problem[0])
                        snprintf(first_problem, sizeof first_problem,
                                 "frame %u: the set for viewpoint %u (%u ids) differs from the local method's (%u ids)%s",
                                 f, set.seq, set.count, count, holds ? "" : " and misses objects it sees");
                }
            }
        }
        /* is the displayed set one that holds where the client is now? */
        if (ref && set.seq) {
            bool valid = set.validity == SL_VIS_POINT ? set.seq == seq
                                                      : sl_vis_reference_cell(ref, &cam) == set.cell;
            invalid += !valid;
        }
    }
    double secs = tool_now() - start;
    sl_vis_client_get_stats(c, &cs);
    qsort(lat, nlat, sizeof *lat, cmp_double);
    double p50 = nlat ? lat[nlat / 2] : 0, p99 = nlat ? lat[(size_t)(0.99 * (nlat - 1))] : 0;
    if (com.json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_string(&j, "method", cs.method);
        cli_json_uint(&j, "frames", frames);
        cli_json_double(&j, "seconds", secs);
        cli_json_uint(&j, "sets_received", cs.sets_received);
        cli_json_uint(&j, "sets_displayed", displayed);
        cli_json_double(&j, "latency_p50_ms", p50);
        cli_json_double(&j, "latency_p99_ms", p99);
        cli_json_uint(&j, "bytes_in", cs.bytes_in);
        cli_json_uint(&j, "connects", cs.connects);
        cli_json_bool(&j, "checked", ref != NULL);
        cli_json_uint(&j, "sets_checked", checked);
        cli_json_uint(&j, "mismatches", mismatches);
        cli_json_uint(&j, "frames_with_invalid_set", invalid);
        cli_json_uint(&j, "timeouts", timeouts);
        cli_json_end(&j);
    } else {
        printf("vis-client: %u frames in %.2f s, %llu sets received, %u displayed, latency p50 %.2f ms p99 %.2f ms, "
               "%llu bytes in, %llu connection(s)\n",
               frames, secs, (unsigned long long)cs.sets_received, displayed, p50, p99,
               (unsigned long long)cs.bytes_in, (unsigned long long)cs.connects);
        if (ref)
            printf("vis-client: --check: %u sets checked, %u mismatches, %u frames displayed a set not valid there\n",
                   checked, mismatches, invalid);
    }
    if (first_problem[0])
        cli_error(a.cmd, "%s", first_problem);
    if (cs.errors)
        cli_error(a.cmd,
                  "%llu connection(s) ended by an error (a refusal by the server or a bad message from it; "
                  "the client reconnected after each); the last: %s",
                  (unsigned long long)cs.errors, cs.last_error);
    if (views_sent && !cs.sets_received) {
        cli_error(a.cmd, "no set received for %u viewpoint(s)", views_sent);
        rc = 1;
    } else if (ref && views_sent && !checked) {
        cli_error(a.cmd, "--check: no set was displayed, none checked");
        rc = 1;
    }
    if (mismatches || timeouts || (stall && invalid))
        rc = 1;
    tool_free(NULL, lat, ((size_t)frames + 1) * sizeof *lat);
    tool_free(NULL, sent, ((size_t)frames + 1) * sizeof *sent);
done:
    if (ids)
        tool_free(NULL, ids, ((size_t)n + 1) * sizeof *ids);
    if (pt)
        tool_free(NULL, pt, ((size_t)n + 1) * sizeof *pt);
    sl_vis_reference_destroy(ref);
    sl_vis_client_destroy(c);
    sl_path_destroy(path);
    sl_scene_destroy(scene);
    return rc;
}
#endif
