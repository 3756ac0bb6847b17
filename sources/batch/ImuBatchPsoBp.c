/**
 * @file ImuBatchPsoBp.c
 * @brief Batch entry points of the PSO-BP gyro bias model (runtime library only, not in the FMU).
 */
#include "ImuPsoBp.h"

/** Return codes of the PSO-BP batch entry points. */
typedef enum {
    ImuBatchPsoBpOk = 0,
    ImuBatchPsoBpNullPointer = -1,   /* an array pointer is NULL (with n > 0) */
    ImuBatchPsoBpBadBlock = -2       /* nBlock != IMU_PSOBP_BLOCK or an entry is invalid */
} ImuBatchPsoBpResult;

/**
 * @brief Run the rate estimator and the model over a series: t (n) [s], temp (n) [degC, NaN
 *        allowed] -> bias_out (n x 3, row-major) [rad/s]. @return 0 or a negative code.
 */
IMU_EXPORT int ImuBatchPsoBpPredict(const double *block, size_t nBlock, size_t n, const double *t,
                                    const double *temp, double *bias_out);
/**
 * @brief Evaluate the networks at given inputs: temp (n) [degC], rate (n) [degC/s] ->
 *        bias_out (n x 3, row-major) [rad/s]. @return 0 or a negative code.
 */
IMU_EXPORT int ImuBatchPsoBpEvaluate(const double *block, size_t nBlock, size_t n, const double *temp,
                                     const double *rate, double *bias_out);
/**
 * @brief Per-sample chain over a series (ImuPsoBpUpdate, then ImuPsoBpCorrect): t (n) [s], temp (n)
 *        [degC, NaN allowed], gyr (n x 3) [rad/s] -> gyr_out = gyr - bias (n x 3) [rad/s].
 *        @return 0 or a negative code.
 */
IMU_EXPORT int ImuBatchPsoBpCorrect(const double *block, size_t nBlock, size_t n, const double *t,
                                    const double *temp, const double *gyr, double *gyr_out);

int ImuBatchPsoBpPredict(const double *block, size_t nBlock, size_t n, const double *t,
                         const double *temp, double *bias_out)
{
    ImuPsoBpCoefficients c;
    ImuPsoBpState s;
    size_t k;
    if (block == NULL || (n > 0 && (t == NULL || temp == NULL || bias_out == NULL))) {
        return ImuBatchPsoBpNullPointer;
    }
    if (ImuPsoBpFromBlock(&c, block, nBlock) != 0) {
        return ImuBatchPsoBpBadBlock;
    }
    ImuPsoBpInitialise(&s, &c);
    for (k = 0; k < n; k++) {
        ImuPsoBpUpdate(&s, t[k], temp[k]);
        ImuPsoBpBias(&c, &s, 1, bias_out + 3 * k); /* clamped: the product's form */
    }
    return ImuBatchPsoBpOk;
}

int ImuBatchPsoBpEvaluate(const double *block, size_t nBlock, size_t n, const double *temp,
                          const double *rate, double *bias_out)
{
    ImuPsoBpCoefficients c;
    size_t k;
    if (block == NULL || (n > 0 && (temp == NULL || rate == NULL || bias_out == NULL))) {
        return ImuBatchPsoBpNullPointer;
    }
    if (ImuPsoBpFromBlock(&c, block, nBlock) != 0) {
        return ImuBatchPsoBpBadBlock;
    }
    for (k = 0; k < n; k++) {
        ImuPsoBpEvaluate(&c, temp[k], rate[k], 1, bias_out + 3 * k);
    }
    return ImuBatchPsoBpOk;
}

int ImuBatchPsoBpCorrect(const double *block, size_t nBlock, size_t n, const double *t,
                         const double *temp, const double *gyr, double *gyr_out)
{
    ImuPsoBpCoefficients c;
    ImuPsoBpState s;
    size_t k;
    int axis;
    if (block == NULL || (n > 0 && (t == NULL || temp == NULL || gyr == NULL || gyr_out == NULL))) {
        return ImuBatchPsoBpNullPointer;
    }
    if (ImuPsoBpFromBlock(&c, block, nBlock) != 0) {
        return ImuBatchPsoBpBadBlock;
    }
    ImuPsoBpInitialise(&s, &c);
    for (k = 0; k < n; k++) {
        for (axis = 0; axis < 3; axis++) {
            gyr_out[3 * k + axis] = gyr[3 * k + axis];
        }
        ImuPsoBpUpdate(&s, t[k], temp[k]);
        ImuPsoBpCorrect(&c, &s, 1, gyr_out + 3 * k);
    }
    return ImuBatchPsoBpOk;
}
