/* LD_PRELOAD shim: the process's realtime clock (CLOCK_REALTIME, gettimeofday, time) reads the real one plus an
 * offset in nanoseconds, a little-endian int64 at the start of the file named by $CLOCK_STEP_FILE, which another
 * process may rewrite at any time: rewriting it steps this process's realtime clock.
 *
 * A real step also moves the deadlines of waits that are in progress: a timed wait against CLOCK_REALTIME (a
 * pthread condition variable with the default clock, pthread_cond_clockwait/clock_nanosleep/sem_timedwait on
 * CLOCK_REALTIME) ends when the stepped clock reaches its deadline. So those waits are translated to the real clock
 * with the offset of the moment and waited in slices of at most SLICE_NS, each slice translated anew: a backward
 * step lengthens a wait in progress by the step, a forward step ends it early, as the kernel would do.
 * Monotonic clocks and waits are left alone. Build: gcc -shared -fPIC -O2 -o shim.so clock_step_shim.c -ldl */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <semaphore.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#define SLICE_NS 50000000LL
#define COND_CLOCK_MONOTONIC_MASK 2u /* glibc >= 2.25: __wrefs bit of a condition variable on CLOCK_MONOTONIC */

static volatile int64_t *offset_map;
static int (*real_clock_gettime)(clockid_t, struct timespec *);
static int (*real_cond_timedwait)(pthread_cond_t *, pthread_mutex_t *, const struct timespec *);
static int (*real_cond_clockwait)(pthread_cond_t *, pthread_mutex_t *, clockid_t, const struct timespec *);
static int (*real_clock_nanosleep)(clockid_t, int, const struct timespec *, struct timespec *);
static int (*real_sem_timedwait)(sem_t *, const struct timespec *);

__attribute__((constructor)) static void shim_init(void) {
    real_clock_gettime = dlsym(RTLD_NEXT, "clock_gettime");
    real_cond_timedwait = dlvsym(RTLD_NEXT, "pthread_cond_timedwait", "GLIBC_2.3.2");
    if (!real_cond_timedwait) real_cond_timedwait = dlsym(RTLD_NEXT, "pthread_cond_timedwait");
    real_cond_clockwait = dlsym(RTLD_NEXT, "pthread_cond_clockwait");
    real_clock_nanosleep = dlsym(RTLD_NEXT, "clock_nanosleep");
    real_sem_timedwait = dlsym(RTLD_NEXT, "sem_timedwait");
    const char *path = getenv("CLOCK_STEP_FILE");
    if (!path) return;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    void *map = mmap(NULL, sizeof(int64_t), PROT_READ, MAP_SHARED, fd, 0);
    close(fd);
    if (map != MAP_FAILED) offset_map = map;
}

static int64_t offset_ns(void) { return offset_map ? __atomic_load_n(offset_map, __ATOMIC_ACQUIRE) : 0; }

static int raw_gettime(clockid_t clk, struct timespec *ts) {
    return real_clock_gettime ? real_clock_gettime(clk, ts) : (int)syscall(SYS_clock_gettime, clk, ts);
}

static int64_t to_ns(const struct timespec *ts) { return (int64_t)ts->tv_sec * 1000000000LL + ts->tv_nsec; }

static struct timespec from_ns(int64_t ns) {
    struct timespec ts;
    ts.tv_sec = ns / 1000000000LL;
    ts.tv_nsec = ns % 1000000000LL;
    if (ts.tv_nsec < 0) { ts.tv_nsec += 1000000000LL; ts.tv_sec -= 1; }
    return ts;
}

static int is_realtime(clockid_t clk) { return clk == CLOCK_REALTIME || clk == CLOCK_REALTIME_COARSE; }

static int64_t real_now_ns(void) { struct timespec ts; raw_gettime(CLOCK_REALTIME, &ts); return to_ns(&ts); }

int clock_gettime(clockid_t clk, struct timespec *ts) {
    int rc = raw_gettime(clk, ts);
    if (rc == 0 && is_realtime(clk)) *ts = from_ns(to_ns(ts) + offset_ns());
    return rc;
}

int gettimeofday(struct timeval *restrict tv, void *restrict tz) {
    (void)tz;
    {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        tv->tv_sec = ts.tv_sec;
        tv->tv_usec = ts.tv_nsec / 1000;
    }
    return 0;
}

time_t time(time_t *out) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    if (out) *out = ts.tv_sec;
    return ts.tv_sec;
}

/* The next real deadline for a wait until the stepped time ``deadline_ns``: that time in real terms, at most one
 * slice away; sets *due when the stepped deadline has passed. */
static struct timespec slice_deadline(int64_t deadline_ns, int *due) {
    int64_t now = real_now_ns();
    int64_t real_deadline = deadline_ns - offset_ns();
    *due = now >= real_deadline;
    return from_ns(real_deadline < now + SLICE_NS ? real_deadline : now + SLICE_NS);
}

static int cond_wait_realtime(pthread_cond_t *cond, pthread_mutex_t *mutex, const struct timespec *abstime) {
    int64_t deadline = to_ns(abstime);
    for (;;) {
        int due;
        struct timespec until = slice_deadline(deadline, &due);
        if (due) return ETIMEDOUT;
        int rc = real_cond_timedwait(cond, mutex, &until);
        if (rc != ETIMEDOUT) return rc;
    }
}

static int cond_is_monotonic(pthread_cond_t *cond) {
    unsigned int wrefs = __atomic_load_n(&cond->__data.__wrefs, __ATOMIC_RELAXED);
    return (wrefs & COND_CLOCK_MONOTONIC_MASK) != 0;
}

int pthread_cond_timedwait(pthread_cond_t *restrict cond, pthread_mutex_t *restrict mutex,
                           const struct timespec *restrict abstime) {
    if (!real_cond_timedwait) return ENOSYS;
    if (cond_is_monotonic(cond) || abstime->tv_sec < 0 || abstime->tv_nsec < 0 || abstime->tv_nsec >= 1000000000L)
        return real_cond_timedwait(cond, mutex, abstime);
    return cond_wait_realtime(cond, mutex, abstime);
}

int pthread_cond_clockwait(pthread_cond_t *restrict cond, pthread_mutex_t *restrict mutex, clockid_t clk,
                           const struct timespec *restrict abstime) {
    if (!real_cond_clockwait) return ENOSYS;
    if (!is_realtime(clk) || abstime->tv_sec < 0 || abstime->tv_nsec < 0 || abstime->tv_nsec >= 1000000000L)
        return real_cond_clockwait(cond, mutex, clk, abstime);
    int64_t deadline = to_ns(abstime);
    for (;;) {
        int due;
        struct timespec until = slice_deadline(deadline, &due);
        if (due) return ETIMEDOUT;
        int rc = real_cond_clockwait(cond, mutex, CLOCK_REALTIME, &until);
        if (rc != ETIMEDOUT) return rc;
    }
}

int clock_nanosleep(clockid_t clk, int flags, const struct timespec *request, struct timespec *remain) {
    if (!real_clock_nanosleep) return ENOSYS;
    if (!is_realtime(clk) || !(flags & TIMER_ABSTIME))
        return real_clock_nanosleep(clk, flags, request, remain);
    int64_t deadline = to_ns(request);
    for (;;) {
        int due;
        struct timespec until = slice_deadline(deadline, &due);
        if (due) return 0;
        int rc = real_clock_nanosleep(CLOCK_REALTIME, TIMER_ABSTIME, &until, NULL);
        if (rc != 0) return rc;
    }
}

int sem_timedwait(sem_t *restrict sem, const struct timespec *restrict abstime) {
    if (!real_sem_timedwait) { errno = ENOSYS; return -1; }
    if (abstime->tv_sec < 0 || abstime->tv_nsec < 0 || abstime->tv_nsec >= 1000000000L)
        return real_sem_timedwait(sem, abstime);
    int64_t deadline = to_ns(abstime);
    for (;;) {
        int due;
        struct timespec until = slice_deadline(deadline, &due);
        if (due) { errno = ETIMEDOUT; return -1; }
        if (real_sem_timedwait(sem, &until) == 0) return 0;
        if (errno != ETIMEDOUT) return -1;
    }
}
