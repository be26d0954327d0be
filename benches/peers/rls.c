/* The hardware reference for vehid's benches: recursive least squares (the Kalman identifier
 * of Eq 4.3-4.7 with F = I, Q = 0) written as a plain C loop, no library, no checks.
 *
 *   rows:   one scalar-output filter per unknown row i (Eq 6.16-6.18), each with its own P_i:
 *           s = x'P_i x + r_i,  theta_i += P_i x (z_i - x'theta_i) / s,  P_i -= (P_i x)(P_i x)'/s
 *   shared: one Q with P_i = r_i Q for every row (valid when r_i / p0 is the same on every
 *           row):  s = x'Q x + 1,  theta_i += Q x (z_i - x'theta_i) / s,  Q -= (Q x)(Q x)'/s
 *
 * P(0) = p0 I (rows) or Q(0) = q0 I (shared), theta(0) = 0. The state dimension is a
 * compile-time constant (4: quarter car, 8: half car) so the compiler can unroll, as vehid's
 * const generics do. Built by benches/peers/crls.py with `cc -O3 -march=native -shared -fPIC`
 * and called through ctypes; one call runs the whole data set, so the call overhead is
 * one ctypes call per run, not per sample.
 *
 * x: n samples of the N-vector regressor (row-major n x N), z: n samples of the N-vector of
 * derivatives (row-major n x N), rows: the K unknown-row indices into z. theta_out: K x N.
 */
#include <stddef.h>
#include <string.h>

#define DEFINE_RLS(N)                                                                          \
    static void rls_rows_##N(const double *restrict x, const double *restrict z, size_t n,     \
                             const int *rows, int k, const double *r, double p0,               \
                             double *restrict theta_out) {                                      \
        double theta[8][N];                                                                     \
        double p[8][N][N];                                                                      \
        memset(theta, 0, sizeof theta);                                                         \
        memset(p, 0, sizeof p);                                                                 \
        for (int i = 0; i < k; i++)                                                             \
            for (int a = 0; a < N; a++) p[i][a][a] = p0;                                        \
        for (size_t t = 0; t < n; t++) {                                                        \
            const double *xt = x + t * N;                                                       \
            for (int i = 0; i < k; i++) {                                                       \
                double px[N];                                                                   \
                double s = r[i], e = z[t * N + rows[i]];                                        \
                for (int a = 0; a < N; a++) {                                                   \
                    double acc = 0.0;                                                           \
                    for (int b = 0; b < N; b++) acc += p[i][a][b] * xt[b];                      \
                    px[a] = acc;                                                                \
                }                                                                               \
                for (int a = 0; a < N; a++) {                                                   \
                    s += xt[a] * px[a];                                                         \
                    e -= xt[a] * theta[i][a];                                                   \
                }                                                                               \
                double inv = 1.0 / s, c = e * inv;                                              \
                for (int a = 0; a < N; a++) theta[i][a] += px[a] * c;                           \
                for (int a = 0; a < N; a++)                                                     \
                    for (int b = 0; b < N; b++) p[i][a][b] -= px[a] * px[b] * inv;              \
            }                                                                                   \
        }                                                                                       \
        for (int i = 0; i < k; i++) memcpy(theta_out + i * N, theta[i], sizeof(double) * N);    \
    }                                                                                           \
    static void rls_shared_##N(const double *restrict x, const double *restrict z, size_t n,   \
                               const int *rows, int k, double q0, double *restrict theta_out) { \
        double theta[8][N];                                                                     \
        double q[N][N];                                                                         \
        memset(theta, 0, sizeof theta);                                                         \
        memset(q, 0, sizeof q);                                                                 \
        for (int a = 0; a < N; a++) q[a][a] = q0;                                               \
        for (size_t t = 0; t < n; t++) {                                                        \
            const double *xt = x + t * N;                                                       \
            double qx[N];                                                                       \
            double s = 1.0;                                                                     \
            for (int a = 0; a < N; a++) {                                                       \
                double acc = 0.0;                                                               \
                for (int b = 0; b < N; b++) acc += q[a][b] * xt[b];                             \
                qx[a] = acc;                                                                    \
            }                                                                                   \
            for (int a = 0; a < N; a++) s += xt[a] * qx[a];                                     \
            double inv = 1.0 / s;                                                               \
            for (int i = 0; i < k; i++) {                                                       \
                double e = z[t * N + rows[i]];                                                  \
                for (int a = 0; a < N; a++) e -= xt[a] * theta[i][a];                           \
                double c = e * inv;                                                             \
                for (int a = 0; a < N; a++) theta[i][a] += qx[a] * c;                           \
            }                                                                                   \
            for (int a = 0; a < N; a++)                                                         \
                for (int b = 0; b < N; b++) q[a][b] -= qx[a] * qx[b] * inv;                     \
        }                                                                                       \
        for (int i = 0; i < k; i++) memcpy(theta_out + i * N, theta[i], sizeof(double) * N);    \
    }

DEFINE_RLS(4)
DEFINE_RLS(8)

/* Returns 0, or -1 for an unsupported state dimension or row count. */
int rls_rows(const double *x, const double *z, size_t n, int nstates, const int *rows, int k,
             const double *r, double p0, double *theta_out) {
    if (k < 1 || k > 8) return -1;
    if (nstates == 4) rls_rows_4(x, z, n, rows, k, r, p0, theta_out);
    else if (nstates == 8) rls_rows_8(x, z, n, rows, k, r, p0, theta_out);
    else return -1;
    return 0;
}

int rls_shared(const double *x, const double *z, size_t n, int nstates, const int *rows, int k,
               double q0, double *theta_out) {
    if (k < 1 || k > 8) return -1;
    if (nstates == 4) rls_shared_4(x, z, n, rows, k, q0, theta_out);
    else if (nstates == 8) rls_shared_8(x, z, n, rows, k, q0, theta_out);
    else return -1;
    return 0;
}
