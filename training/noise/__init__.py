"""Noise characterisation by Allan deviation (issue 34, item 1): white noise density, bias instability
and random walk per axis from any still data, with confidence intervals and support flags; the
imufusion-noise/1 block (model.json "noise"), Kalibr's imu.yaml and Allan deviation plots.

allan.py: pooled overlapping Allan variance (allantools) and the IEEE 952 fit; characterise.py: still
stretches -> the block; kalibr.py: imu.yaml; plot.py: PNG per triad; report.py: `imufmu noise` outputs.
"""
