/**
 * @file ImuBatchSize.c
 * @brief Memory of the runtime structs, for the benchmarks (runtime shared library only, not in the FMU).
 */
#include <stddef.h>
#include "model.h"

/**
 * @brief Sizes [bytes] of the attitude filter, the whole pipeline and the FMI-independent FMU
 *        instance (ModelInstance: the pipeline, the parameter/input/output values and the FMU
 *        state; the FMI 2 wrapper adds five pointers and the instance name).
 */
IMU_EXPORT void ImuBatchSizes(size_t *attitude, size_t *pipeline, size_t *instance);

void ImuBatchSizes(size_t *attitude, size_t *pipeline, size_t *instance)
{
    *attitude = sizeof(ImuAttitude);
    *pipeline = sizeof(ImuPipeline);
    *instance = sizeof(ModelInstance);
}
