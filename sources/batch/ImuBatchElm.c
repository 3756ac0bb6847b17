/**
 * @file ImuBatchElm.c
 * @brief Batch entry point of the ELM field model for the runtime shared library (not in the FMU).
 */
#include <stddef.h>
#include "ImuElm.h"

/**
 * @brief Apply the ELM block (IMU_ELM_BLOCK doubles, ImuElm.h) to n fields in (row-major n x 3,
 *        uT) into out (n x 3, uT).
 * @return 0; -1 a NULL pointer, -2 nBlock != IMU_ELM_BLOCK, -3 an invalid block.
 */
IMU_EXPORT int ImuBatchElmPredict(const double *block, size_t nBlock, size_t n, const double *in,
                                  double *out);

int ImuBatchElmPredict(const double *block, size_t nBlock, size_t n, const double *in, double *out)
{
    ImuElm elm;
    size_t k;
    if (block == NULL || in == NULL || out == NULL) {
        return -1;
    }
    if (nBlock != IMU_ELM_BLOCK) {
        return -2;
    }
    if (ImuElmFromBlock(&elm, block) != 0) {
        return -3;
    }
    for (k = 0; k < n; k++) {
        ImuElmApply(&elm, in + 3 * k, out + 3 * k);
    }
    return 0;
}
