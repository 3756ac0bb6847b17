/**
 * @file ImuMagPfNet.c
 * @brief Mode 0 of the magnetometer particle filter, steps 5-6: double-threshold splitting and
 *        diversity restoration by a small back-propagation network, and the roughening sigma
 *        (docs/magpf.md; called by ImuMagPfSplit.c).
 */
#include <math.h>
#include "ImuMagPfPrivate.h"

#define IMU_MAG_PF_HILL_FRACTION 0.9 /* Hill number of the m new weights must exceed 0.9 m */
#define IMU_MAG_PF_NETWORK_INIT 0.5  /* initial network weights ~ U(-0.5, 0.5) */
#define IMU_MAG_PF_TINY 1e-12        /* scale below which a normalisation uses 1 */

/** @brief Mean and standard deviation (returned) of n values read with a stride. */
static double ImuMagPfMoments(const double *values, int n, int stride, double *mean)
{
    double sum = 0.0, squares = 0.0;
    int s;
    for (s = 0; s < n; s++) {
        sum += values[s * stride];
    }
    *mean = sum / n;
    for (s = 0; s < n; s++) {
        const double d = values[s * stride] - *mean;
        squares += d * d;
    }
    return sqrt(squares / n);
}

/** @brief Normalisation gain 1 / sd, or 1 when sd is negligible against the mean. */
static double ImuMagPfGain(double sd, double mean)
{
    return sd > IMU_MAG_PF_TINY * (fabs(mean) + 1.0) ? 1.0 / sd : 1.0;
}

/** @brief Hidden activations tanh(W1 xn + b1) of a state x; returns the normalised output. */
static double ImuMagPfForward(const ImuMagPfNetwork *net, int hiddenUnits, const double x[IMU_MAG_PF_STATE_SIZE],
                              double hidden[IMU_MAG_PF_MAX_HIDDEN])
{
    double output = net->b2;
    int u, j;
    for (u = 0; u < hiddenUnits; u++) {
        double a = net->b1[u];
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            a += net->w1[u][j] * ((x[j] - net->inputMean[j]) * net->inputScale[j]);
        }
        hidden[u] = tanh(a);
        output += net->w2[u] * hidden[u];
    }
    return output;
}

/** @brief Network prediction of the log likelihood l(x) [1] of a state x. */
static double ImuMagPfPredictLikelihood(ImuMagPf *pf, const double x[IMU_MAG_PF_STATE_SIZE])
{
    const ImuMagPfNetwork *net = &pf->work.network;
    const double out = ImuMagPfForward(net, pf->settings.hiddenUnits, x, pf->work.hidden[0]);
    return out / net->outputScale + net->outputMean;
}

/** @brief Normalisation of the training set (first count high-weight particles) and random weights. */
static void ImuMagPfNetworkSetUp(ImuMagPf *pf, int count)
{
    ImuMagPfWork *w = &pf->work;
    ImuMagPfNetwork *net = &w->network;
    double sd;
    int s, u, j;
    for (s = 0; s < count; s++) {
        w->copy[s][0] = w->logLikelihood[w->high[s]];
    }
    sd = ImuMagPfMoments(&w->copy[0][0], count, IMU_MAG_PF_STATE_SIZE, &net->outputMean);
    net->outputScale = ImuMagPfGain(sd, net->outputMean);
    for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
        for (s = 0; s < count; s++) {
            w->copy[s][0] = pf->particle[w->high[s]][j];
        }
        sd = ImuMagPfMoments(&w->copy[0][0], count, IMU_MAG_PF_STATE_SIZE, &net->inputMean[j]);
        net->inputScale[j] = ImuMagPfGain(sd, net->inputMean[j]);
    }
    for (u = 0; u < pf->settings.hiddenUnits; u++) {
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            net->w1[u][j] = IMU_MAG_PF_NETWORK_INIT * (2.0 * ImuRngUniform(&pf->rng) - 1.0);
        }
        net->b1[u] = IMU_MAG_PF_NETWORK_INIT * (2.0 * ImuRngUniform(&pf->rng) - 1.0);
        net->w2[u] = IMU_MAG_PF_NETWORK_INIT * (2.0 * ImuRngUniform(&pf->rng) - 1.0);
    }
    net->b2 = 0.0;
}

/** @brief One full-batch gradient-descent epoch on the mean squared error (normalised units). */
static void ImuMagPfTrainEpoch(ImuMagPf *pf, int count)
{
    ImuMagPfWork *w = &pf->work;
    ImuMagPfNetwork *net = &w->network;
    const int hiddenUnits = pf->settings.hiddenUnits;
    const double step = pf->settings.learningRate / count;
    double gradB2 = 0.0;
    int s, u, j;
    for (s = 0; s < count; s++) {
        const double target = (w->logLikelihood[w->high[s]] - net->outputMean) * net->outputScale;
        w->error[s] = ImuMagPfForward(net, hiddenUnits, pf->particle[w->high[s]], w->hidden[s]) - target;
        gradB2 += w->error[s];
    }
    for (u = 0; u < hiddenUnits; u++) {
        double gradW2 = 0.0, gradB1 = 0.0, gradW1[IMU_MAG_PF_STATE_SIZE] = {0.0};
        for (s = 0; s < count; s++) {
            const double *x = pf->particle[w->high[s]];
            const double delta = w->error[s] * net->w2[u] * (1.0 - w->hidden[s][u] * w->hidden[s][u]);
            gradW2 += w->error[s] * w->hidden[s][u];
            gradB1 += delta;
            for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
                gradW1[j] += delta * ((x[j] - net->inputMean[j]) * net->inputScale[j]);
            }
        }
        net->w2[u] -= step * gradW2;
        net->b1[u] -= step * gradB1;
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            net->w1[u][j] -= step * gradW1[j];
        }
    }
    net->b2 -= step * gradB2;
}

/** @brief Train the network on the high-weight particles' states against their log likelihoods. */
static void ImuMagPfTrain(ImuMagPf *pf, int nHigh)
{
    const int count = nHigh < IMU_MAG_PF_MAX_TRAINING ? nHigh : IMU_MAG_PF_MAX_TRAINING;
    int epoch;
    ImuMagPfNetworkSetUp(pf, count);
    for (epoch = 0; epoch < pf->settings.trainingEpochs; epoch++) {
        ImuMagPfTrainEpoch(pf, count);
    }
}

/** @brief Write n-1 roughened copies of each high-weight particle into the low-weight slots. */
static void ImuMagPfJitterCopies(ImuMagPf *pf, int nHigh, int n, const double sigma[IMU_MAG_PF_STATE_SIZE])
{
    ImuMagPfWork *w = &pf->work;
    int f, c, j, slot = 0;
    for (f = 0; f < nHigh; f++) {
        for (c = 0; c < n - 1; c++, slot++) {
            const int target = w->low[slot];
            w->parent[slot] = w->high[f];
            for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
                pf->particle[target][j] = pf->particle[w->high[f]][j] + sigma[j] * ImuRngNormal(&pf->rng);
            }
        }
    }
}

/** @brief Tempered log likelihood ratios copy/parent alpha (l(copy) - l(parent)) from the network
 *         outputs into work.logWeight; returns their Hill number. */
static double ImuMagPfDiversity(ImuMagPf *pf, int m, double alpha)
{
    ImuMagPfWork *w = &pf->work;
    double largest = -HUGE_VAL, sum = 0.0, entropy = 0.0;
    int s;
    for (s = 0; s < m; s++) {
        const double lc = ImuMagPfPredictLikelihood(pf, pf->particle[w->low[s]]);
        const double lp = ImuMagPfPredictLikelihood(pf, pf->particle[w->parent[s]]);
        w->logWeight[w->low[s]] = alpha * (lc - lp);
        largest = w->logWeight[w->low[s]] > largest ? w->logWeight[w->low[s]] : largest;
    }
    for (s = 0; s < m; s++) {
        sum += exp(w->logWeight[w->low[s]] - largest);
    }
    for (s = 0; s < m; s++) {
        const double p = exp(w->logWeight[w->low[s]] - largest) / sum;
        entropy -= p > 0.0 ? p * log(p) : 0.0;
    }
    return exp(entropy);
}

/** @brief Split weights: parent keeps w/n, its n-1 copies share (n-1) w/n by likelihood ratio. */
static void ImuMagPfAssignSplitWeights(ImuMagPf *pf, int nHigh, int n)
{
    ImuMagPfWork *w = &pf->work;
    int f, c;
    for (f = 0; f < nHigh; f++) {
        const int first = f * (n - 1);
        const double share = pf->weight[w->high[f]] / n;
        double largest = -HUGE_VAL, sum = 0.0;
        for (c = 0; c < n - 1; c++) {
            const double l = w->logWeight[w->low[first + c]];
            largest = l > largest ? l : largest;
        }
        for (c = 0; c < n - 1; c++) {
            sum += exp(w->logWeight[w->low[first + c]] - largest);
        }
        for (c = 0; c < n - 1; c++) {
            pf->weight[w->low[first + c]] = (n - 1) * share * exp(w->logWeight[w->low[first + c]] - largest) / sum;
        }
        pf->weight[w->high[f]] = share;
    }
}

/** @brief Roughening sigma per state component: K N^(-1/9) x (unweighted) standard deviation of the cloud. */
void ImuMagPfCloudSigma(const ImuMagPf *pf, double sigma[IMU_MAG_PF_STATE_SIZE])
{
    const int n = pf->settings.particleCount;
    double mean;
    int j;
    for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
        sigma[j] = pf->coefficients.rougheningScale * ImuMagPfMoments(&pf->particle[0][j], n, IMU_MAG_PF_STATE_SIZE, &mean);
    }
}

/** @brief Steps 5-6: double-threshold splitting with network-based diversity restoration; alpha is
 *         the tempering exponent of the update. */
void ImuMagPfNetSplit(ImuMagPf *pf, double alpha)
{
    ImuMagPfWork *w = &pf->work;
    double sigma[IMU_MAG_PF_STATE_SIZE];
    int nHigh = 0, nLow = 0, n, i, j, tries;
    for (i = 0; i < pf->settings.particleCount; i++) {
        if (pf->weight[i] > pf->coefficients.highWeight) {
            w->high[nHigh++] = i;
        } else if (pf->weight[i] < pf->coefficients.lowWeight) {
            w->low[nLow++] = i;
        }
    }
    if (nHigh == 0 || nLow / nHigh < 2) {
        return;
    }
    n = nLow / nHigh;
    ImuMagPfCloudSigma(pf, sigma);
    ImuMagPfTrain(pf, nHigh);
    for (tries = 0; tries < pf->settings.maxTries; tries++) {
        ImuMagPfJitterCopies(pf, nHigh, n, sigma);
        if (ImuMagPfDiversity(pf, nHigh * (n - 1), alpha) > IMU_MAG_PF_HILL_FRACTION * nHigh * (n - 1)) {
            break;
        }
        for (j = 0; j < IMU_MAG_PF_STATE_SIZE; j++) {
            sigma[j] *= 0.5;
        }
    }
    ImuMagPfAssignSplitWeights(pf, nHigh, n);
}
