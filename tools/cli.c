/* Shared command-line helpers: errors, option parsing, progress bar, JSON writer. */
#include "cli.h"

#include "tool.h"
#include "sightline/cull.h"
#include "sightline/import.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

void cli_error(const char *cmd, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "sightline %s: ", cmd);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

int cli_fail(const char *cmd, const sl_error *err)
{
    /* a library message that names the command already ("pvs update: ...") is not prefixed twice;
     * only a command of two words, which a file name given as an argument is not likely to be */
    const char *m = err->message[0] ? err->message : "failed";
    size_t n = strlen(cmd);
    if (strchr(cmd, ' ') && !strncmp(m, cmd, n) && m[n] == ':' && m[n + 1] == ' ')
        m += n + 2;
    cli_error(cmd, "%s (%s)", m, sl_status_string(err->status));
    return 1;
}

void cli_args_init(cli_args *a, int argc, char **argv)
{
    a->argc = argc;
    a->argv = argv;
    a->i = 1;
    a->cmd = argv[0];
    a->error = false;
    a->unknown[0] = 0;
}

bool cli_common_option(cli_args *a, const char *name, const char *value, unsigned which, cli_common *c)
{
    if (name && !strcmp(name, "help")) {
        c->help = true;
        a->i = a->argc; /* the parse ends here */
        return true;
    }
    if (!name) {
        if ((which & CLI_OUTPUT) && !strcmp(value, "-o")) {
            c->output = cli_value(a, "o", NULL);
            return true;
        }
        if (!(which & CLI_INPUT))
            return false;
        if (c->input)
            cli_unknown(a, NULL);
        else
            c->input = value;
        return true;
    }
    if ((which & CLI_OUTPUT) && !strcmp(name, "output")) {
        c->output = cli_value(a, name, value);
    } else if ((which & CLI_MAP) && !strcmp(name, "map")) {
        c->map = cli_value(a, name, value);
    } else if ((which & CLI_JSON) && !strcmp(name, "json")) {
        c->json = true;
    } else if ((which & CLI_QUIET) && !strcmp(name, "quiet")) {
        c->quiet = true;
    } else {
        return false;
    }
    return true;
}

int cli_parse_done(const cli_args *a, const cli_common *c, void (*usage)(FILE *))
{
    if (c->help) {
        usage(stdout);
        return 0;
    }
    if (a->error && a->unknown[0])
        cli_suggest_option(a->cmd, a->unknown, usage);
    return a->error ? 2 : -1;
}

#define CLI_SUGGEST_MAX 256
#define CLI_SUGGEST_WORD 48

void cli_suggest_option(const char *cmd, const char *name, void (*usage)(FILE *))
{
    if (!usage || !name || !name[0])
        return;
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    if (!f)
        return;
    usage(f);
    if (fclose(f) != 0 || !text) {
        free(text);
        return;
    }
    /* the "--word" tokens of the text, each once */
    char(*words)[CLI_SUGGEST_WORD] = malloc(CLI_SUGGEST_MAX * CLI_SUGGEST_WORD);
    const char *list[CLI_SUGGEST_MAX];
    size_t n = 0;
    for (const char *p = text; words && (p = strstr(p, "--")) != NULL && n < CLI_SUGGEST_MAX;) {
        const char *q = p + 2;
        size_t k = 0;
        while ((isalnum((unsigned char)q[k]) || q[k] == '-') && k + 3 < CLI_SUGGEST_WORD)
            k++;
        if (k > 0 && (p == text || !isalnum((unsigned char)p[-1]))) {
            snprintf(words[n], CLI_SUGGEST_WORD, "--%.*s", (int)k, q);
            bool dup = false;
            for (size_t i = 0; i < n && !dup; i++)
                dup = !strcmp(words[i], words[n]);
            if (!dup) {
                list[n] = words[n];
                n++;
            }
        }
        p = q + k;
    }
    char word[80], out[200];
    snprintf(word, sizeof word, "--%s", name);
    if (words && sl_text_suggest(word, list, n, out, sizeof out) > 0)
        cli_error(cmd, "did you mean %s?", out);
    free(words);
    free(text);
}

int cli_action(int argc, char **argv, const char *cmd, void (*usage)(FILE *), const char *const *names, int count,
               int *status)
{
    *status = 2;
    if (argc < 2) {
        usage(stderr);
        return -1;
    }
    const char *action = argv[1];
    if (!strcmp(action, "--help") || !strcmp(action, "-h") || !strcmp(action, "help")) {
        usage(stdout);
        *status = 0;
        return -1;
    }
    for (int i = 0; i < count; i++)
        if (!strcmp(action, names[i]))
            return i;
    char list[256] = "";
    size_t n = 0;
    for (int i = 0; i < count && n < sizeof list; i++)
        n += (size_t)snprintf(list + n, sizeof list - n, "%s%s", i == 0 ? "" : i + 1 == count ? " or " : ", ", names[i]);
    cli_error(cmd, "unknown action '%s' (%s; see sightline %s --help)", action, list, cmd);
    return -1;
}

bool cli_next(cli_args *a, const char **name, const char **inline_value)
{
    if (a->error || a->i >= a->argc)
        return false;
    char *arg = a->argv[a->i++];
    *inline_value = NULL;
    if (arg[0] == '-' && arg[1] == '-' && arg[2]) {
        char *buf = a->namebuf;
        const char *eq = strchr(arg + 2, '=');
        if (eq) {
            size_t n = (size_t)(eq - (arg + 2));
            if (n >= sizeof a->namebuf)
                n = sizeof a->namebuf - 1;
            memcpy(buf, arg + 2, n);
            buf[n] = 0;
            *name = buf;
            *inline_value = eq + 1;
        } else {
            *name = arg + 2;
        }
        return true;
    }
    if (arg[0] == '-' && arg[1] == 'h' && !arg[2]) {
        *name = "help";
        return true;
    }
    *name = NULL;
    *inline_value = arg;
    return true;
}

const char *cli_value(cli_args *a, const char *name, const char *inline_value)
{
    if (inline_value)
        return inline_value;
    if (a->i >= a->argc) {
        cli_error(a->cmd, "option --%s needs a value", name);
        a->error = true;
        return NULL;
    }
    return a->argv[a->i++];
}

bool cli_parse_u64(cli_args *a, const char *name, const char *text, uint64_t *out)
{
    if (!text)
        return false;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(text, &end, 10);
    if (!text[0] || *end || errno || text[0] == '-') {
        cli_error(a->cmd, "--%s: '%s' is not a non-negative integer", name, text);
        a->error = true;
        return false;
    }
    *out = v;
    return true;
}

bool cli_parse_u32(cli_args *a, const char *name, const char *text, uint32_t *out)
{
    uint64_t v;
    if (!cli_parse_u64(a, name, text, &v))
        return false;
    if (v > UINT32_MAX) {
        cli_error(a->cmd, "--%s: %s is too large", name, text);
        a->error = true;
        return false;
    }
    *out = (uint32_t)v;
    return true;
}

bool cli_parse_threads(cli_args *a, const char *name, const char *text, bool zero_ok, uint32_t *out)
{
    uint64_t v;
    if (!cli_parse_u64(a, name, text, &v))
        return false;
    char what[64];
    snprintf(what, sizeof what, "--%s", name);
    sl_error err;
    if (sl_threads_check(v > UINT32_MAX ? UINT32_MAX : (uint32_t)v, zero_ok, what, &err) != SL_OK) {
        cli_error(a->cmd, "%s", err.message);
        a->error = true;
        return false;
    }
    *out = (uint32_t)v;
    return true;
}

bool cli_parse_float(cli_args *a, const char *name, const char *text, float *out)
{
    if (!text)
        return false;
    char *end;
    errno = 0;
    float v = strtof(text, &end);
    if (!text[0] || *end || errno || !isfinite(v)) {
        cli_error(a->cmd, "--%s: '%s' is not a finite number", name, text);
        a->error = true;
        return false;
    }
    *out = v;
    return true;
}

void cli_unknown(cli_args *a, const char *name)
{
    if (name) {
        cli_error(a->cmd, "unknown option --%s (see sightline %s --help)", name, a->cmd);
        if (!a->unknown[0])
            snprintf(a->unknown, sizeof a->unknown, "%s", name);
    }
    else
        cli_error(a->cmd, "unexpected argument '%s' (see sightline %s --help)", a->i > 0 ? a->argv[a->i - 1] : "",
                  a->cmd);
    a->error = true;
}

/* ---- --allow-external ---- */

bool cli_import_option(cli_args *a, const char *name, const char *inline_value, cli_import *imp)
{
    if (name && strcmp(name, "import-timeout") == 0) {
        const char *v = cli_value(a, name, inline_value);
        if (!v)
            return true;
        char *end = NULL;
        errno = 0;
        double sec = strtod(v, &end);
        /* whole milliseconds, at least one, that fit the option's 32 bits */
        if (!v[0] || *end || errno || !(sec >= 0.001) || sec > 4294967.0) {
            cli_error(a->cmd, "--import-timeout: '%s' is not a number of seconds from 0.001 to 4294967", v);
            a->error = true;
        } else {
            imp->timeout_ms = (uint32_t)(sec * 1000.0 + 0.5);
        }
        return true;
    }
    if (!name || strcmp(name, "allow-external") != 0)
        return false;
    const char *v = cli_value(a, name, inline_value);
    if (!v)
        return true;
    if (!v[0]) {
        cli_error(a->cmd, "--allow-external needs a path");
        a->error = true;
    } else if (imp->count == CLI_ALLOW_EXTERNAL_MAX) {
        cli_error(a->cmd, "--allow-external: at most %d paths", CLI_ALLOW_EXTERNAL_MAX);
        a->error = true;
    } else {
        imp->allow[imp->count++] = v;
    }
    return true;
}

void cli_import_apply(const cli_import *imp, sl_import_options *opt)
{
    opt->allow_external = imp->count ? imp->allow : NULL;
    opt->allow_external_count = imp->count;
    opt->timeout_ms = imp->timeout_ms;
}

/* ---- progress ---- */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void json_str(FILE *out, const char *s);

/* "1:02:03", "2:03" */
static void put_hms(char *out, size_t size, double s)
{
    if (!(s >= 0) || s > 359999)
        s = 359999;
    unsigned t = (unsigned)(s + 0.5), h = t / 3600, m = t / 60 % 60, sec = t % 60;
    if (h)
        snprintf(out, size, "%u:%02u:%02u", h, m, sec);
    else
        snprintf(out, size, "%u:%02u", m, sec);
}

static bool progress_cb(void *user, const char *stage, uint64_t done, uint64_t total)
{
    cli_progress_state *st = user;
    if (!st->enabled)
        return true;
    double t = now_s();
    bool new_stage = strncmp(st->stage, stage, sizeof st->stage - 1) != 0;
    bool last = total && done >= total;
    if (!new_stage && t - st->last_draw < (st->json ? 1.0 : 0.1) && !last)
        return true;
    if (new_stage) {
        snprintf(st->stage, sizeof st->stage, "%s", stage);
        st->stage_start = t;
    }
    st->last_draw = t;
    double el = t - st->stage_start, rate = el > 0 ? (double)done / el : 0;
    bool eta_known = total && done > 0 && el > 0;
    double eta = eta_known ? (double)(total > done ? total - done : 0) / rate : 0;
    if (st->json) {
        fputs("{\"progress\":", stderr);
        json_str(stderr, stage);
        fprintf(stderr, ",\"done\":%llu,\"total\":%llu,\"elapsed_s\":%.3f,\"eta_s\":", (unsigned long long)done,
                (unsigned long long)total, el);
        if (eta_known)
            fprintf(stderr, "%.3f", eta);
        else
            fputs("null", stderr);
        fprintf(stderr, ",\"rate\":%.3f}\n", rate);
        fflush(stderr);
        return true;
    }
    char els[24], etas[24];
    put_hms(els, sizeof els, el);
    if (eta_known)
        put_hms(etas, sizeof etas, eta);
    else
        snprintf(etas, sizeof etas, "?");
    if (total) {
        int width = 24, fill = (int)((double)done / (double)total * width);
        if (fill > width)
            fill = width;
        fprintf(stderr, "\r\033[K%-20.20s [%.*s%*s] %5.1f%% %llu/%llu %.1f/s elapsed %s ETA %s", stage, fill,
                "########################", width - fill, "", 100.0 * (double)done / (double)total,
                (unsigned long long)done, (unsigned long long)total, rate, els, etas);
    } else {
        fprintf(stderr, "\r\033[K%-20.20s %llu %.1f/s elapsed %s", stage, (unsigned long long)done, rate, els);
    }
    fflush(stderr);
    return true;
}

sl_progress cli_progress(cli_progress_state *st, bool quiet)
{
    memset(st, 0, sizeof *st);
    const char *ci = getenv("CI");
    st->enabled = !quiet && isatty(STDERR_FILENO) && !(ci && ci[0]);
    sl_progress p = {progress_cb, st};
    return p;
}

sl_progress cli_progress_json(cli_progress_state *st)
{
    memset(st, 0, sizeof *st);
    st->enabled = st->json = true;
    sl_progress p = {progress_cb, st};
    return p;
}

void cli_progress_done(cli_progress_state *st)
{
    if (st->enabled && !st->json && st->stage[0]) {
        fprintf(stderr, "\r\033[K");
        fflush(stderr);
    }
    st->stage[0] = 0;
}

/* ---- JSON ---- */

static void json_sep(cli_json *j)
{
    if (j->need_comma[j->depth])
        fputc(',', j->out);
    j->need_comma[j->depth] = true;
}

static void json_str(FILE *out, const char *s)
{
    fputc('"', out);
    /* control characters (C0, DEL, C1) as \\u escapes; a byte that is not well-formed UTF-8 as the
     * \\u escape of its Latin-1 code point, so that the output stays valid JSON */
    for (const unsigned char *p = (const unsigned char *)s; *p;) {
        size_t n = sl_utf8_sequence(p, strnlen((const char *)p, 4));
        if (*p == '"' || *p == '\\') {
            fprintf(out, "\\%c", *p++);
        } else if (*p < 0x20 || *p == 0x7f) {
            fprintf(out, "\\u%04x", *p++);
        } else if (n) {
            fwrite(p, 1, n, out);
            p += n;
        } else if (p[0] == 0xc2 && p[1] >= 0x80 && p[1] <= 0x9f) {
            fprintf(out, "\\u%04x", p[1]);
            p += 2;
        } else {
            fprintf(out, "\\u%04x", *p++);
        }
    }
    fputc('"', out);
}

void cli_json_key(cli_json *j, const char *key)
{
    json_sep(j);
    if (key) {
        json_str(j->out, key);
        fputc(':', j->out);
    }
}

void cli_json_begin(cli_json *j, FILE *out)
{
    memset(j, 0, sizeof *j);
    j->out = out;
    fputc('{', out);
    j->depth = 1;
}

void cli_json_end(cli_json *j)
{
    fputs("}\n", j->out);
    j->depth = 0;
}

void cli_json_object_begin(cli_json *j, const char *key)
{
    cli_json_key(j, key);
    fputc('{', j->out);
    if (j->depth < 31)
        j->depth++;
    j->need_comma[j->depth] = false;
}

void cli_json_object_end(cli_json *j)
{
    fputc('}', j->out);
    j->depth--;
}

void cli_json_array_begin(cli_json *j, const char *key)
{
    cli_json_key(j, key);
    fputc('[', j->out);
    if (j->depth < 31)
        j->depth++;
    j->need_comma[j->depth] = false;
}

void cli_json_array_end(cli_json *j)
{
    fputc(']', j->out);
    j->depth--;
}

void cli_json_string(cli_json *j, const char *key, const char *value)
{
    cli_json_key(j, key);
    if (value)
        json_str(j->out, value);
    else
        fputs("null", j->out);
}

void cli_json_int(cli_json *j, const char *key, int64_t v)
{
    cli_json_key(j, key);
    fprintf(j->out, "%lld", (long long)v);
}

void cli_json_uint(cli_json *j, const char *key, uint64_t v)
{
    cli_json_key(j, key);
    fprintf(j->out, "%llu", (unsigned long long)v);
}

void cli_json_double(cli_json *j, const char *key, double v)
{
    cli_json_key(j, key);
    if (isfinite(v))
        fprintf(j->out, "%.9g", v);
    else
        fputs("null", j->out);
}

void cli_json_bool(cli_json *j, const char *key, bool v)
{
    cli_json_key(j, key);
    fputs(v ? "true" : "false", j->out);
}

const char *cli_bytes(uint64_t bytes, char *buf, size_t size)
{
    const char *units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    double v = (double)bytes;
    int u = 0;
    while (v >= 1024 && u < 4)
        v /= 1024, u++;
    snprintf(buf, size, u ? "%.2f %s" : "%.0f %s", v, units[u]);
    return buf;
}

uint64_t cli_peak_rss(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return 0;
    char line[256];
    uint64_t kb = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "VmHWM:", 6))
            kb = strtoull(line + 6, NULL, 10);
    fclose(f);
    return kb * 1024;
}

bool cli_output_not_input(const char *cmd, const char *output, const char *const *inputs, size_t count)
{
    struct stat so;
    if (!output)
        return true;
    /* a folder (or socket) is refused now, before any long work, not when the file is written */
    size_t len = strlen(output);
    if (len && output[len - 1] == '/') {
        cli_error(cmd, "%s: cannot write: it names a directory (give a file name)", output);
        return false;
    }
    if (stat(output, &so) != 0)
        return true;
    if (S_ISDIR(so.st_mode) || S_ISSOCK(so.st_mode)) {
        cli_error(cmd, "%s: cannot write: it is a %s (give a file name)", output,
                  S_ISDIR(so.st_mode) ? "directory" : "socket");
        return false;
    }
    for (size_t i = 0; i < count; i++) {
        struct stat si;
        if (inputs[i] && stat(inputs[i], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino) {
            if (!strcmp(inputs[i], output))
                cli_error(cmd, "the output %s is the input file; give another output name", output);
            else
                cli_error(cmd, "the output %s is the input file %s; give another output name", output, inputs[i]);
            return false;
        }
    }
    return true;
}

/* ---- output folders ---- */

#define STAGE_BASE ".sightline-run"

/* Remove a stage folder: its regular files, then the folder (what else is in it stays). */
static void remove_stage(const char *stage)
{
    DIR *d = opendir(stage);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        struct stat st;
        if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(st.st_mode))
            unlinkat(dirfd(d), e->d_name, 0);
    }
    closedir(d);
    rmdir(stage);
}

/* Remove the stages "<dir>/<base>.tmp.<pid>.<hex>" whose process is gone (folders only). */
static void remove_stale_stages(const char *dir, const char *base)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    long self = (long)getpid();
    struct dirent *e;
    while ((e = readdir(d))) {
        long pid;
        struct stat st;
        if (!sl_output_temp_name_pid(base, e->d_name, &pid) || pid == self)
            continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH)
            continue;
        if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISDIR(st.st_mode))
            continue;
        char path[8400];
        if (snprintf(path, sizeof path, "%s/%s", dir, e->d_name) < (int)sizeof path)
            remove_stage(path);
    }
    closedir(d);
}

/* mkdir -p of every folder above path (not path itself). */
static bool make_parents(const char *path)
{
    char buf[4096];
    if (snprintf(buf, sizeof buf, "%s", path) >= (int)sizeof buf)
        return false;
    for (char *p = buf + 1; *p; p++) {
        if (*p != '/')
            continue;
        *p = 0;
        if (mkdir(buf, 0755) != 0 && errno != EEXIST)
            return false;
        *p = '/';
    }
    return true;
}

bool cli_outdir_begin(const char *cmd, const char *dir, cli_outdir *od)
{
    memset(od, 0, sizeof *od);
    size_t n = strlen(dir);
    while (n > 1 && dir[n - 1] == '/')
        n--;
    if (n == 0 || n >= sizeof od->target) {
        cli_error(cmd, "the output folder name '%s' is %s", dir, n ? "too long" : "empty");
        return false;
    }
    memcpy(od->target, dir, n);
    od->target[n] = 0;
    uint64_t tag = (uint64_t)(uintptr_t)od ^ (uint64_t)(tool_now() * 1e9);
    long pid = (long)getpid();
    struct stat st;
    if (stat(od->target, &st) == 0) {
        if (!S_ISDIR(st.st_mode)) {
            cli_error(cmd, "the output folder '%s' exists and is not a folder", od->target);
            return false;
        }
        remove_stale_stages(od->target, STAGE_BASE);
        snprintf(od->stage, sizeof od->stage, "%s/%s.tmp.%ld.%016llx", od->target, STAGE_BASE, pid,
                 (unsigned long long)tag);
    } else if (errno == ENOENT) {
        od->fresh = true;
        if (!make_parents(od->target)) {
            cli_error(cmd, "cannot create the folders above the output folder '%s': %s", od->target, strerror(errno));
            return false;
        }
        const char *slash = strrchr(od->target, '/');
        char parent[4096];
        snprintf(parent, sizeof parent, "%.*s", slash ? (int)(slash - od->target + (slash == od->target)) : 1,
                 slash ? od->target : ".");
        remove_stale_stages(parent, slash ? slash + 1 : od->target);
        snprintf(od->stage, sizeof od->stage, "%s.tmp.%ld.%016llx", od->target, pid, (unsigned long long)tag);
    } else {
        cli_error(cmd, "cannot use the output folder '%s': %s", od->target, strerror(errno));
        return false;
    }
    if (mkdir(od->stage, 0755) != 0) {
        cli_error(cmd, "cannot create a folder for this run's files beside '%s': %s", od->target, strerror(errno));
        return false;
    }
    od->open = true;
    return true;
}

/* text with every "stage/" as "out/", from malloc; NULL when out of memory */
static char *stage_to_out(const char *text, const char *stage, const char *out)
{
    size_t sl = strlen(stage), ol = strlen(out), hits = 0;
    for (const char *p = strstr(text, stage); p; p = strstr(p + sl, stage))
        hits += p[sl] == '/';
    char *s = malloc(strlen(text) + hits * ol + 1), *w = s;
    if (!s)
        return NULL;
    for (const char *p = text; *p;) {
        if (hits && !strncmp(p, stage, sl) && p[sl] == '/') {
            memcpy(w, out, ol);
            w += ol;
            p += sl;
        } else {
            *w++ = *p++;
        }
    }
    *w = 0;
    return s;
}

sl_status cli_outdir_show_bench(sl_bench bench, const char *stage, const char *out, sl_error *err)
{
    if (!stage || !*stage || !out)
        return SL_OK;
    for (uint32_t i = 0, n = sl_bench_method_count(bench); i < n; i++) {
        sl_bench_method_info info;
        sl_status st = sl_bench_method(bench, i, &info, err);
        if (st != SL_OK)
            return st;
        char *shown = stage_to_out(info.options, stage, out);
        if (!shown)
            return tool_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
        st = strcmp(shown, info.options) ? sl_bench_set_shown_options(bench, i, shown, err) : SL_OK;
        free(shown);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

void cli_outdir_abort(cli_outdir *od)
{
    if (od->open)
        remove_stage(od->stage);
    od->open = false;
}

bool cli_outdir_commit(const char *cmd, cli_outdir *od)
{
    if (!od->open)
        return false;
    if (od->fresh) {
        if (rename(od->stage, od->target) == 0) {
            od->open = false;
            return true;
        }
        if (errno != EEXIST && errno != ENOTEMPTY) {
            cli_error(cmd, "cannot move this run's files to '%s': %s", od->target, strerror(errno));
            cli_outdir_abort(od);
            return false;
        }
        /* the folder appeared meanwhile: move the files into it as below */
    }
    DIR *d = opendir(od->stage);
    if (!d) {
        cli_error(cmd, "cannot read this run's folder '%s': %s", od->stage, strerror(errno));
        cli_outdir_abort(od);
        return false;
    }
    /* first check that every file can take its place (a folder of the same name cannot be
     * replaced), so that a refusal leaves the target untouched */
    bool ok = true;
    char from[8400], to[8400];
    struct dirent *e;
    for (int pass = 0; pass < 2 && ok; pass++) {
        rewinddir(d);
        while (ok && (e = readdir(d))) {
            struct stat st;
            if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(st.st_mode))
                continue;
            snprintf(from, sizeof from, "%s/%s", od->stage, e->d_name);
            snprintf(to, sizeof to, "%s/%s", od->target, e->d_name);
            if (pass == 0) {
                if (lstat(to, &st) == 0 && S_ISDIR(st.st_mode)) {
                    cli_error(cmd, "cannot write %s: it is a folder (nothing of this run was moved to '%s')", to,
                              od->target);
                    ok = false;
                } else if (!cli_output_not_input(cmd, to, od->inputs, od->input_count)) {
                    cli_error(cmd, "nothing of this run was moved to '%s'", od->target);
                    ok = false;
                }
            } else if (rename(from, to) != 0) {
                cli_error(cmd, "cannot move %s to %s: %s (the files before it were moved)", from, to, strerror(errno));
                ok = false;
            }
        }
    }
    closedir(d);
    cli_outdir_abort(od);
    return ok;
}

int cli_method_list(const char *cmd, const char *text, char *buf, size_t buf_size, sl_bench_method_spec *specs,
                    uint32_t max)
{
    if (snprintf(buf, buf_size, "%s", text) >= (int)buf_size) {
        cli_error(cmd, "--methods: list too long");
        return -1;
    }
    int n = 0;
    sl_error err;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        char *opts = strchr(tok, ':');
        if (opts) {
            *opts++ = 0;
            for (char *c = opts; *c; c++)
                if (*c == ':')
                    *c = ',';
            if (!*opts) {
                cli_error(cmd, "--methods: '%s:' has no options after the colon", tok);
                return -1;
            }
        }
        uint32_t index;
        if (sl_cull_method_find(tok, &index, &err) != SL_OK) {
            cli_error(cmd, "--methods: %s", err.message);
            return -1;
        }
        for (int k = 0; k < n; k++)
            if (!strcmp(specs[k].name, tok)) {
                cli_error(cmd, "--methods: '%s' is listed twice", tok);
                return -1;
            }
        if (n == (int)max) {
            cli_error(cmd, "--methods: at most %u methods", max);
            return -1;
        }
        specs[n++] = (sl_bench_method_spec){.name = tok, .options = opts};
    }
    if (!n) {
        cli_error(cmd, "--methods: empty list");
        return -1;
    }
    return n;
}

void cli_drop_not_applicable(const char *cmd, sl_scene scene, const char *label, sl_bench_method_spec *run,
                             uint32_t *n, sl_bench_skip *skipped, uint32_t *nskipped, uint32_t max, bool quiet)
{
    uint32_t kept = 0;
    for (uint32_t i = 0; i < *n; i++) {
        bool ok = true;
        char why[400];
        sl_error err;
        if (sl_cull_method_applicable(run[i].name, run[i].options, scene, &ok, why, sizeof why, &err) != SL_OK)
            ok = true;
        if (ok) {
            run[kept++] = run[i];
            continue;
        }
        if (!quiet)
            cli_error(cmd, "not running %s on %s: not applicable: %s", run[i].name, label, why);
        if (*nskipped < max) {
            skipped[*nskipped].name = run[i].name;
            snprintf(skipped[*nskipped].reason, sizeof skipped[0].reason, "%.80s: not applicable: %.390s", label, why);
            (*nskipped)++;
        }
    }
    *n = kept;
}
