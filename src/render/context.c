/* Headless GL contexts through EGL (render_internal.h, "Context"): the device platform
 * (EGL_EXT_platform_device, a device with a hardware driver) or Mesa's surfaceless platform
 * (llvmpipe without a GPU); an OpenGL 4.5 core context made current without a surface. */
#include "render/render_internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

sl_status sl_render_fail(sl_error *err, sl_status status, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
        err->status = status;
    }
    return status;
}

double sl_render_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static const char *egl_error_name(EGLint e)
{
    switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return "EGL error";
    }
}

static bool has_word(const char *list, const char *word)
{
    size_t n = strlen(word);
    for (const char *p = list; p && (p = strstr(p, word)) != NULL; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0'))
            return true;
    return false;
}

/* A display of the device platform on the first device with a hardware driver (not Mesa's
 * software device), or EGL_NO_DISPLAY with the reason in why. */
static EGLDisplay device_display(char *why, size_t why_size)
{
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!has_word(client, "EGL_EXT_platform_device") || !has_word(client, "EGL_EXT_device_enumeration")) {
        snprintf(why, why_size, "EGL has no EGL_EXT_platform_device / EGL_EXT_device_enumeration");
        return EGL_NO_DISPLAY;
    }
    PFNEGLQUERYDEVICESEXTPROC query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    PFNEGLQUERYDEVICESTRINGEXTPROC device_string =
        (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
    if (!query_devices || !device_string) {
        snprintf(why, why_size, "eglQueryDevicesEXT is missing");
        return EGL_NO_DISPLAY;
    }
    EGLDeviceEXT devices[16];
    EGLint n = 0;
    if (!query_devices(16, devices, &n) || n <= 0) {
        snprintf(why, why_size, "eglQueryDevicesEXT found no device");
        return EGL_NO_DISPLAY;
    }
    for (EGLint i = 0; i < n; i++) {
        const char *ext = device_string(devices[i], EGL_EXTENSIONS);
        if (has_word(ext, "EGL_MESA_device_software"))
            continue;
        EGLDisplay d = eglGetPlatformDisplay(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL);
        if (d != EGL_NO_DISPLAY)
            return d;
    }
    snprintf(why, why_size, "no EGL device with a hardware driver (%d device(s), software only)", (int)n);
    return EGL_NO_DISPLAY;
}

static sl_status context_on(EGLDisplay d, bool debug, EGLContext *out, char *why, size_t why_size)
{
    EGLint major = 0, minor = 0;
    if (!eglInitialize(d, &major, &minor)) {
        snprintf(why, why_size, "eglInitialize: %s", egl_error_name(eglGetError()));
        return SL_ERROR_UNSUPPORTED;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        snprintf(why, why_size, "eglBindAPI(EGL_OPENGL_API): %s", egl_error_name(eglGetError()));
        return SL_ERROR_UNSUPPORTED;
    }
    EGLConfig config = NULL;
    const char *ext = eglQueryString(d, EGL_EXTENSIONS);
    if (!has_word(ext, "EGL_KHR_no_config_context") && !has_word(ext, "EGL_MESA_configless_context")) {
        const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
        EGLint got = 0;
        if (!eglChooseConfig(d, want, &config, 1, &got) || got < 1) {
            snprintf(why, why_size, "eglChooseConfig: no OpenGL config");
            return SL_ERROR_UNSUPPORTED;
        }
    }
    if (!has_word(ext, "EGL_KHR_surfaceless_context")) {
        snprintf(why, why_size, "the display has no EGL_KHR_surfaceless_context");
        return SL_ERROR_UNSUPPORTED;
    }
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                              EGL_CONTEXT_OPENGL_DEBUG, debug ? EGL_TRUE : EGL_FALSE, EGL_NONE};
    EGLContext c = eglCreateContext(d, config, EGL_NO_CONTEXT, attribs);
    if (c == EGL_NO_CONTEXT) {
        snprintf(why, why_size, "eglCreateContext(OpenGL 4.5 core): %s", egl_error_name(eglGetError()));
        return SL_ERROR_UNSUPPORTED;
    }
    if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
        snprintf(why, why_size, "eglMakeCurrent(no surface): %s", egl_error_name(eglGetError()));
        eglDestroyContext(d, c);
        return SL_ERROR_UNSUPPORTED;
    }
    *out = c;
    return SL_OK;
}

sl_status sl_render_context_make(sl_gl_context_kind kind, bool debug, EGLDisplay *display, EGLContext *context,
                                 sl_gl_context_kind *made, sl_error *err)
{
    char why_device[200] = "", why_surfaceless[200] = "";
    if (kind == SL_GL_CONTEXT_AUTO || kind == SL_GL_CONTEXT_DEVICE) {
        EGLDisplay d = device_display(why_device, sizeof why_device);
        if (d != EGL_NO_DISPLAY && context_on(d, debug, context, why_device, sizeof why_device) == SL_OK) {
            *display = d;
            *made = SL_GL_CONTEXT_DEVICE;
            return SL_OK;
        }
        if (kind == SL_GL_CONTEXT_DEVICE)
            return sl_render_fail(err, SL_ERROR_UNSUPPORTED, "no headless GL context (EGL device platform): %s",
                                  why_device);
    }
    if (kind == SL_GL_CONTEXT_AUTO || kind == SL_GL_CONTEXT_SURFACELESS) {
        const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
        if (!has_word(client, "EGL_MESA_platform_surfaceless")) {
            snprintf(why_surfaceless, sizeof why_surfaceless, "EGL has no EGL_MESA_platform_surfaceless");
        } else {
            EGLDisplay d = eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
            if (d == EGL_NO_DISPLAY)
                snprintf(why_surfaceless, sizeof why_surfaceless, "eglGetPlatformDisplay(surfaceless): %s",
                         egl_error_name(eglGetError()));
            else if (context_on(d, debug, context, why_surfaceless, sizeof why_surfaceless) == SL_OK) {
                *display = d;
                *made = SL_GL_CONTEXT_SURFACELESS;
                return SL_OK;
            }
        }
        if (kind == SL_GL_CONTEXT_SURFACELESS)
            return sl_render_fail(err, SL_ERROR_UNSUPPORTED, "no headless GL context (EGL surfaceless platform): %s",
                                  why_surfaceless);
        return sl_render_fail(err, SL_ERROR_UNSUPPORTED, "no headless GL context: device platform: %s; surfaceless: %s",
                              why_device, why_surfaceless);
    }
    return sl_render_fail(err, SL_ERROR_INVALID_ARGUMENT, "context kind %d is not a headless kind", (int)kind);
}

/* The display stays initialised: EGL hands every caller of the same platform the same display,
 * and eglTerminate would end the contexts of every other renderer on it (EGL counts no
 * references); the driver stays loaded for the process, as in any GL program. */
void sl_render_context_release(EGLDisplay display, EGLContext context)
{
    if (display == EGL_NO_DISPLAY)
        return;
    if (eglGetCurrentContext() == context)
        eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context != EGL_NO_CONTEXT)
        eglDestroyContext(display, context);
}

sl_status sl_renderer_probe(sl_gl_context_kind kind, sl_error *err)
{
    if (kind == SL_GL_CONTEXT_CURRENT) {
        if (eglGetCurrentContext() == EGL_NO_CONTEXT && !glGetString(GL_VERSION))
            return sl_render_fail(err, SL_ERROR_UNSUPPORTED, "no GL context is current on this thread");
        return SL_OK;
    }
    EGLDisplay d = EGL_NO_DISPLAY;
    EGLContext c = EGL_NO_CONTEXT;
    sl_gl_context_kind made;
    sl_status st = sl_render_context_make(kind, false, &d, &c, &made, err);
    if (st != SL_OK)
        return st;
    sl_render_context_release(d, c);
    return SL_OK;
}

/* ---- errors ---- */

static const char *gl_error_name(GLenum e)
{
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "GL error";
    }
}

void APIENTRY sl_render_debug_callback(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                                         const GLchar *message, const void *user)
{
    sl_renderer r = (sl_renderer)(uintptr_t)user;
    if (type != GL_DEBUG_TYPE_ERROR && severity != GL_DEBUG_SEVERITY_HIGH)
        return;
    if (r->debug_pending)
        return; /* the first one is the cause */
    r->debug_pending = true;
    int n = length < 0 ? (int)strlen(message) : (int)length;
    snprintf(r->debug_message, sizeof r->debug_message, "%.*s", n, message);
}

sl_status sl_render_check(sl_renderer r, const char *what, sl_error *err)
{
    GLenum e = glGetError();
    GLenum first = e;
    while (e != GL_NO_ERROR)
        e = glGetError(); /* drain */
    if (first == GL_NO_ERROR && !r->debug_pending)
        return SL_OK;
    sl_status st = first == GL_OUT_OF_MEMORY ? SL_ERROR_OUT_OF_MEMORY : SL_ERROR_INTERNAL;
    if (first != GL_NO_ERROR && r->debug_pending)
        sl_render_fail(err, st, "%s: %s: %s", what, gl_error_name(first), r->debug_message);
    else if (first != GL_NO_ERROR)
        sl_render_fail(err, st, "%s: %s", what, gl_error_name(first));
    else
        sl_render_fail(err, st, "%s: driver message: %s", what, r->debug_message);
    r->debug_pending = false;
    return st;
}

sl_status sl_render_enter(sl_renderer r, const char *what, sl_error *err)
{
    if (r->own_context && eglGetCurrentContext() != r->egl_context &&
        !eglMakeCurrent(r->egl_display, EGL_NO_SURFACE, EGL_NO_SURFACE, r->egl_context))
        return sl_render_fail(err, SL_ERROR_INTERNAL, "%s: eglMakeCurrent: %s", what, egl_error_name(eglGetError()));
    char label[160];
    snprintf(label, sizeof label, "before %s (a GL call outside the renderer)", what);
    return sl_render_check(r, label, err);
}
