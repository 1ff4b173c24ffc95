"""The BARN benchmark (Perille et al. 2020; github.com/Daffan/the-barn-challenge, MIT license):
its 300 static worlds, reference paths, score and published DWA rows."""
