"""analysis.stats against full-precision reference values computed in R.

Every constant below was printed by R 4.2.2 (Debian r-base-core 4.2.2, "R version 4.2.2
Patched (2022-11-10 r83330)") with ``sprintf("%.17g", ...)`` by the script in ``R_SCRIPT``
(run it with ``Rscript`` to regenerate). R is not needed to run these tests.

Sources of the reference values:

* ``kruskal.test`` help page example, Hollander & Wolfe (1973, p. 116)      -> HW_KW
* ``kruskal.test(Ozone ~ Month, data = airquality)`` (help page example;
  37 NA ozone values, dropped by na.omit)                                    -> AQ_KW
* ``kruskal.test(count ~ spray, data = InsectSprays)`` (heavily tied counts) -> IS_KW
* ``kruskal.test(weight ~ group, data = PlantGrowth)``                       -> PG_KW
* ``p.adjust`` help page example (``set.seed(123)``; p-values printed from R,
  including its NA example ``pN[c(46, 47)] <- NA``)                          -> PADJ_*
* ``wilcox.test(x, y, exact = FALSE, correct = FALSE)`` on the help page's
  two-sample example, Hollander & Wolfe (1973, p. 69f), on airquality months
  5 vs 8 (help page formula example) and on InsectSprays A vs C (ties)       -> *_MW
* Dunn's test: FSA is not in Debian, so Z, P.unadj and P.adj (FSA::dunnTest's
  columns, method = "holm") were computed by hand in R from Dunn's formula
  z_ij = (Rbar_i - Rbar_j) / sqrt((N(N+1)/12 - sum(t^3 - t)/(12(N-1))) (1/n_i + 1/n_j)),
  p = 2 * pnorm(-|z|), then p.adjust(p, "holm")                              -> *_DUNN_*
* Dunn's test again, against rstatix::dunn_test (rstatix 0.7.2, the published
  implementation Debian packages), two-sided, Holm                           -> *_RSTATIX_*
* Pairwise Kruskal-Wallis: kruskal.test on each pair's subset, then
  p.adjust(p, "holm") across the pairs                                       -> *_PKW_*
* Cohen's d / Hedges' g / d_z: by hand in R from the textbook formulas with
  var() and sd() (ddof = 1); no R package involved                           -> *_D, *_G, *_DZ
"""

import math

import numpy as np
import pandas as pd
import pytest

import analysis

RTOL = 1e-10
nan = float("nan")

R_SCRIPT = r"""
f <- function(v) paste0("[", paste(ifelse(is.na(v), "nan", sprintf("%.17g", v)), collapse=", "), "]")
s <- function(v) sprintf("%.17g", v)
cat("R_VERSION =", shQuote(R.version.string, type="cmd"), "\n")
# 1. kruskal.test help example (Hollander & Wolfe 1973, p. 116)
x <- c(2.9, 3.0, 2.5, 2.6, 3.2); y <- c(3.8, 2.7, 4.0, 2.4); z <- c(2.8, 3.4, 3.7, 2.2, 2.0)
k <- kruskal.test(list(x, y, z))
cat("HW_KW = dict(H=", s(k$statistic), ", df=", s(k$parameter), ", p=", s(k$p.value), ")\n", sep="")
# 2. airquality Ozone ~ Month
k <- kruskal.test(Ozone ~ Month, data = airquality)
cat("AQ_KW = dict(H=", s(k$statistic), ", df=", s(k$parameter), ", p=", s(k$p.value), ")\n", sep="")
cat("AQ_OZONE =", f(airquality$Ozone), "\n")
cat("AQ_MONTH =", f(airquality$Month), "\n")
# 3. InsectSprays (heavy ties)
k <- kruskal.test(count ~ spray, data = InsectSprays)
cat("IS_KW = dict(H=", s(k$statistic), ", df=", s(k$parameter), ", p=", s(k$p.value), ")\n", sep="")
cat("IS_COUNT =", f(InsectSprays$count), "\n")
cat("IS_SPRAY =", paste0("[", paste0("'", as.character(InsectSprays$spray), "'", collapse=", "), "]"), "\n")
# PlantGrowth
k <- kruskal.test(weight ~ group, data = PlantGrowth)
cat("PG_KW = dict(H=", s(k$statistic), ", df=", s(k$parameter), ", p=", s(k$p.value), ")\n", sep="")
cat("PG_WEIGHT =", f(PlantGrowth$weight), "\n")
cat("PG_GROUP =", paste0("[", paste0("'", as.character(PlantGrowth$group), "'", collapse=", "), "]"), "\n")
# 4. p.adjust help example
set.seed(123)
xx <- rnorm(50, mean = c(rep(0, 25), rep(3, 25)))
p <- 2*pnorm(sort(-abs(xx)))
cat("PADJ_P =", f(p), "\n")
cat("PADJ_HOLM =", f(p.adjust(p, "holm")), "\n")
cat("PADJ_BH =", f(p.adjust(p, "BH")), "\n")
cat("PADJ_BONF =", f(p.adjust(p, "bonferroni")), "\n")
pN <- p; iN <- c(46, 47); pN[iN] <- NA
cat("PADJ_PN =", f(pN), "\n")
cat("PADJ_HOLM_NA =", f(p.adjust(pN, "holm")), "\n")
cat("PADJ_BH_NA =", f(p.adjust(pN, "BH")), "\n")
cat("PADJ_BONF_NA =", f(p.adjust(pN, "bonferroni")), "\n")
pe <- c(0, 1, 0.5, 1e-300, 0.01, 0.01, NA, 1)
cat("PADJ_EDGE =", f(pe), "\n")
cat("PADJ_EDGE_HOLM =", f(p.adjust(pe, "holm")), "\n")
cat("PADJ_EDGE_BH =", f(p.adjust(pe, "BH")), "\n")
# 5. wilcox.test two-sample example (H&W 1973, p. 69f), asymptotic, no correction, two-sided
x <- c(0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46); y <- c(1.15, 0.88, 0.90, 0.74, 1.21)
w <- wilcox.test(x, y, exact = FALSE, correct = FALSE)
cat("HW_MW = dict(U=", s(w$statistic), ", p=", s(w$p.value), ")\n", sep="")
# airquality months 5 vs 8 (wilcox.test help formula example), asymptotic (ties) no correction
w <- wilcox.test(Ozone ~ Month, data = airquality, subset = Month %in% c(5, 8), exact=FALSE, correct=FALSE)
cat("AQ58_MW = dict(U=", s(w$statistic), ", p=", s(w$p.value), ")\n", sep="")
# InsectSprays A vs C (ties)
w <- wilcox.test(InsectSprays$count[InsectSprays$spray=="A"], InsectSprays$count[InsectSprays$spray=="C"], exact=FALSE, correct=FALSE)
cat("IS_AC_MW = dict(U=", s(w$statistic), ", p=", s(w$p.value), ")\n", sep="")
# 6. Dunn's test by hand (formula of Dunn 1964 as in FSA::dunnTest / dunn.test), Holm across pairs
dunn_by_hand <- function(v, g, prefix) {
  ok <- !is.na(v); v <- v[ok]; g <- factor(g[ok]); N <- length(v)
  r <- rank(v); t <- table(v)
  S2 <- N*(N+1)/12 - sum(t^3 - t)/(12*(N-1))
  lev <- levels(g); Rbar <- tapply(r, g, mean); n <- tapply(r, g, length)
  A <- c(); B <- c(); Z <- c()
  for (i in 1:(length(lev)-1)) for (j in (i+1):length(lev)) {
    A <- c(A, lev[i]); B <- c(B, lev[j])
    Z <- c(Z, (Rbar[i] - Rbar[j]) / sqrt(S2 * (1/n[i] + 1/n[j])))
  }
  P <- 2*pnorm(-abs(Z))
  cat(prefix, "_DUNN_A = ", paste0("[", paste0("'", A, "'", collapse=", "), "]"), "\n", sep="")
  cat(prefix, "_DUNN_B = ", paste0("[", paste0("'", B, "'", collapse=", "), "]"), "\n", sep="")
  cat(prefix, "_DUNN_Z = ", f(Z), "\n", sep="")
  cat(prefix, "_DUNN_P = ", f(P), "\n", sep="")
  cat(prefix, "_DUNN_PADJ = ", f(p.adjust(P, "holm")), "\n", sep="")
}
dunn_by_hand(PlantGrowth$weight, PlantGrowth$group, "PG")
dunn_by_hand(InsectSprays$count, InsectSprays$spray, "IS")
dunn_by_hand(airquality$Ozone, airquality$Month, "AQ")
# 7. pairwise Kruskal-Wallis + Holm
pairwise_kw <- function(v, g, prefix) {
  ok <- !is.na(v); v <- v[ok]; g <- factor(g[ok]); lev <- levels(g)
  A <- c(); B <- c(); H <- c(); P <- c()
  for (i in 1:(length(lev)-1)) for (j in (i+1):length(lev)) {
    sel <- g %in% c(lev[i], lev[j])
    k <- kruskal.test(v[sel], droplevels(g[sel]))
    A <- c(A, lev[i]); B <- c(B, lev[j]); H <- c(H, k$statistic); P <- c(P, k$p.value)
  }
  cat(prefix, "_PKW_H = ", f(H), "\n", sep="")
  cat(prefix, "_PKW_P = ", f(P), "\n", sep="")
  cat(prefix, "_PKW_PADJ = ", f(p.adjust(P, "holm")), "\n", sep="")
}
pairwise_kw(airquality$Ozone, airquality$Month, "AQ")
pairwise_kw(InsectSprays$count, InsectSprays$spray, "IS")
# 8. Cohen's d and Hedges' g by hand (pooled SD with ddof=1), paired d_z
cd <- function(a, b) { n1 <- length(a); n2 <- length(b)
  sp <- sqrt(((n1-1)*var(a) + (n2-1)*var(b))/(n1+n2-2)); (mean(a)-mean(b))/sp }
x <- c(0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46); y <- c(1.15, 0.88, 0.90, 0.74, 1.21)
d <- cd(x, y); cat("HW_D =", s(d), "\n"); cat("HW_G =", s(d*(1-3/(4*(length(x)+length(y))-9))), "\n")
xp <- c(1.83,  0.50,  1.62,  2.48, 1.68, 1.88, 1.55, 3.06, 1.30)
yp <- c(0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.14, 1.29)
cat("HW_DZ =", s(mean(xp-yp)/sd(xp-yp)), "\n")
a <- PlantGrowth$weight[PlantGrowth$group=="trt1"]; b <- PlantGrowth$weight[PlantGrowth$group=="ctrl"]
cat("PG_T1_CTRL_D =", s(cd(a, b)), "\n")
a <- PlantGrowth$weight[PlantGrowth$group=="trt2"]
cat("PG_T2_CTRL_D =", s(cd(a, b)), "\n")
cat("PG_MEANSD = ", f(tapply(PlantGrowth$weight, PlantGrowth$group, mean)), "  # ", f(tapply(PlantGrowth$weight, PlantGrowth$group, sd)), "\n")
w <- wilcox.test(PlantGrowth$weight[PlantGrowth$group=="trt1"], b, exact=FALSE, correct=FALSE)$p.value
w2 <- wilcox.test(PlantGrowth$weight[PlantGrowth$group=="trt2"], b, exact=FALSE, correct=FALSE)$p.value
cat("PG_MW_P = ", f(c(w, w2)), "\n")
"""

# ---------------------------------------------------------------------------------------------
# Values printed by R_SCRIPT (R 4.2.2).
# ---------------------------------------------------------------------------------------------
R_VERSION = "R version 4.2.2 Patched (2022-11-10 r83330)"
HW_KW = dict(H=0.77142857142857224, df=2, p=0.67996477357889362)
AQ_KW = dict(H=29.266576306116939, df=4, p=6.9007141185467839e-06)
AQ_OZONE = [
    41, 36, 12, 18, nan, 28, 23, 19, 8, nan, 7, 16, 11, 14, 18, 14, 34, 6, 30, 11, 1, 11, 4, 32, nan, nan,
    nan, 23, 45, 115, 37, nan, nan, nan, nan, nan, nan, 29, nan, 71, 39, nan, nan, 23, nan, nan, 21, 37,
    20, 12, 13, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, 135, 49, 32, nan, 64, 40, 77, 97, 97,
    85, nan, 10, 27, nan, 7, 48, 35, 61, 79, 63, 16, nan, nan, 80, 108, 20, 52, 82, 50, 64, 59, 39, 9, 16,
    78, 35, 66, 122, 89, 110, nan, nan, 44, 28, 65, nan, 22, 59, 23, 31, 44, 21, 9, nan, 45, 168, 73, nan,
    76, 118, 84, 85, 96, 78, 73, 91, 47, 32, 20, 23, 21, 24, 44, 21, 28, 9, 13, 46, 18, 13, 24, 16, 13,
    23, 36, 7, 14, 30, nan, 14, 18, 20,
]
AQ_MONTH = [5] * 31 + [6] * 30 + [7] * 31 + [8] * 31 + [9] * 30
IS_KW = dict(H=54.691344622371446, df=5, p=1.5108444394185103e-10)
IS_COUNT = [
    10, 7, 20, 14, 14, 12, 10, 23, 17, 20, 14, 13, 11, 17, 21, 11, 16, 14, 17, 17, 19, 21, 7, 13, 0, 1, 7,
    2, 3, 1, 2, 1, 3, 0, 1, 4, 3, 5, 12, 6, 4, 3, 5, 5, 5, 5, 2, 4, 3, 5, 3, 5, 3, 6, 1, 1, 3, 2, 6, 4,
    11, 9, 15, 22, 15, 16, 13, 10, 26, 26, 24, 13,
]
IS_SPRAY = [s for s in "ABCDEF" for _ in range(12)]
PG_KW = dict(H=7.9882287494437154, df=2, p=0.01842375573147197)
PG_WEIGHT = [
    4.17, 5.58, 5.18, 6.11, 4.5, 4.61, 5.17, 4.53, 5.33, 5.14, 4.81, 4.17, 4.41, 3.59, 5.87, 3.83, 6.03,
    4.89, 4.32, 4.69, 6.31, 5.12, 5.54, 5.5, 5.37, 5.29, 4.92, 6.15, 5.8, 5.26,
]
PG_GROUP = ["ctrl"] * 10 + ["trt1"] * 10 + ["trt2"] * 10
PADJ_P = [
    2.3540535079793408e-07, 2.1015902407242859e-05, 2.5768418740401113e-05, 9.8147833236073584e-05,
    0.00010526095883054314, 0.0001241480728928015, 0.00013259880192358452, 0.00015685033125567761,
    0.00022545573276267595, 0.00037953803092710003, 0.00061149431534094181, 0.0016139537290707732,
    0.0033024296231373793, 0.0035383417761100746, 0.0052369965805745761, 0.0068319089314331019,
    0.0070592256589326078, 0.0088051286010114201, 0.0094010398396727739, 0.01129798083228886,
    0.021150168138838837, 0.049227364030420349, 0.06053297750530709, 0.062622394673603865,
    0.073951528932168428, 0.082811032824038747, 0.086333312789586975, 0.11906543306177111,
    0.18907962539672907, 0.20584937780834683, 0.22092137198443099, 0.28560004255989702,
    0.30488948730835402, 0.46606820025984125, 0.48308093523371298, 0.4921754604884912,
    0.53194528606277292, 0.5751550464079549, 0.57831946234574394, 0.61858943409521261,
    0.63636200475135141, 0.64485872428665469, 0.65584143928443872, 0.68858840005799427,
    0.71898636230424384, 0.81795385305609414, 0.82744865669079792, 0.89712997590579502,
    0.91186795243409247, 0.94378902178378343,
]
PADJ_HOLM = [
    1.1770267539896705e-05, 0.0010297792179549, 0.0012368840995392533, 0.0046129481620954581,
    0.0048420041062049845, 0.0055866632801760676, 0.0058343472846377189, 0.0067445642439941372,
    0.0094691407760323903, 0.015561059268011102, 0.024459772613637673, 0.062944195433760147,
    0.12549232567922042, 0.13091864571607276, 0.18853187690068474, 0.23911681260015857,
    0.24001367240370866, 0.29056924383337684, 0.30083327486952877, 0.35023740580095469,
    0.63450504416516507, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
    1, 1,
]
PADJ_BH = [
    1.1770267539896705e-05, 0.0004294736456733519, 0.0004294736456733519, 0.00094713429945417519,
    0.00094713429945417519, 0.00094713429945417519, 0.00094713429945417519, 0.00098031457034798513,
    0.0012525318486815331, 0.0018976901546355002, 0.0027795196151860994, 0.0067248072044615555,
    0.012636934914678839, 0.012636934914678839, 0.017456655268581922, 0.020762428408625317,
    0.020762428408625317, 0.024458690558365054, 0.024739578525454671, 0.028244952080722151,
    0.050357543187711518, 0.11188037279640989, 0.13046332223667473, 0.13046332223667473,
    0.14790305786433686, 0.15925198620007452, 0.15987650516590179, 0.21261684475316273,
    0.32599935413229147, 0.34308229634724474, 0.35632479352327578, 0.44625006649983912,
    0.46195376864902127, 0.6835770284562378, 0.6835770284562378, 0.6835770284562378, 0.71884498116590934,
    0.74143520813556918, 0.74143520813556918, 0.76260632474934742, 0.76260632474934742,
    0.76260632474934742, 0.76260632474934742, 0.78248681824772082, 0.79887373589360433,
    0.88026452839446589, 0.88026452839446589, 0.93047750248376782, 0.93047750248376782,
    0.94378902178378343,
]
PADJ_BONF = [
    1.1770267539896705e-05, 0.001050795120362143, 0.0012884209370200557, 0.0049073916618036792,
    0.0052630479415271573, 0.0062074036446400751, 0.006629940096179226, 0.007842516562783881,
    0.011272786638133797, 0.018976901546355, 0.030574715767047091, 0.080697686453538656,
    0.16512148115686898, 0.17691708880550372, 0.26184982902872883, 0.34159544657165508,
    0.35296128294663037, 0.44025643005057102, 0.47005199198363867, 0.56489904161444304, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
]
PADJ_PN = [
    2.3540535079793408e-07, 2.1015902407242859e-05, 2.5768418740401113e-05, 9.8147833236073584e-05,
    0.00010526095883054314, 0.0001241480728928015, 0.00013259880192358452, 0.00015685033125567761,
    0.00022545573276267595, 0.00037953803092710003, 0.00061149431534094181, 0.0016139537290707732,
    0.0033024296231373793, 0.0035383417761100746, 0.0052369965805745761, 0.0068319089314331019,
    0.0070592256589326078, 0.0088051286010114201, 0.0094010398396727739, 0.01129798083228886,
    0.021150168138838837, 0.049227364030420349, 0.06053297750530709, 0.062622394673603865,
    0.073951528932168428, 0.082811032824038747, 0.086333312789586975, 0.11906543306177111,
    0.18907962539672907, 0.20584937780834683, 0.22092137198443099, 0.28560004255989702,
    0.30488948730835402, 0.46606820025984125, 0.48308093523371298, 0.4921754604884912,
    0.53194528606277292, 0.5751550464079549, 0.57831946234574394, 0.61858943409521261,
    0.63636200475135141, 0.64485872428665469, 0.65584143928443872, 0.68858840005799427,
    0.71898636230424384, nan, nan, 0.89712997590579502, 0.91186795243409247, 0.94378902178378343,
]
PADJ_HOLM_NA = [
    1.1299456838300836e-05, 0.00098774741314041443, 0.0011853472620584511, 0.0044166524956233116,
    0.0046314821885438985, 0.0053383671343904641, 0.0055691496807905496, 0.0064308635814827823,
    0.0090182293105070376, 0.014801983206156902, 0.02323678398295579, 0.059716287975618607,
    0.11888746643294565, 0.12384196216385261, 0.1780578837395356, 0.22545299473729236,
    0.22589522108584345, 0.27295898663135404, 0.28203119519018321, 0.32764144413637697,
    0.59220470788748747, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, nan, nan,
    1, 1, 1,
]
PADJ_BH_NA = [
    1.1299456838300836e-05, 0.0004122946998464178, 0.0004122946998464178, 0.00090924892747600808,
    0.00090924892747600808, 0.00090924892747600808, 0.00090924892747600808, 0.00094110198753406566,
    0.0012024305747342717, 0.0018217825484500801, 0.002668338830578655, 0.0064558149162830926,
    0.012131457518091684, 0.012131457518091684, 0.016758389057838646, 0.019931931272280306,
    0.019931931272280306, 0.023480342936030452, 0.023749995384436479, 0.027115153997493265,
    0.048343241460203051, 0.10740515788455349, 0.12524478934720773, 0.12524478934720773,
    0.14198693554976338, 0.15288190675207153, 0.15348144495926572, 0.20411217096303619,
    0.31295937996699985, 0.32935900449335498, 0.34207180178234475, 0.42840006383984552,
    0.44347561790306039, 0.65623394731798823, 0.65623394731798823, 0.65623394731798823,
    0.69009118191927299, 0.71177779981014644, 0.71177779981014644, 0.73210207175937347,
    0.73210207175937347, 0.73210207175937347, 0.73210207175937347, 0.75118734551781186,
    0.76691878645786005, nan, nan, 0.93126939823056243, 0.93126939823056243, 0.94378902178378343,
]
PADJ_BONF_NA = [
    1.1299456838300836e-05, 0.0010087633155476572, 0.0012368840995392533, 0.0047110959953315318,
    0.0050525260238660705, 0.0059591074988544716, 0.0063647424923320567, 0.0075288159002725253,
    0.010821875172608447, 0.018217825484500801, 0.029351727136365205, 0.077469778995397115,
    0.15851662191059421, 0.16984040525328359, 0.25137583586757967, 0.32793162870878889,
    0.33884283162876516, 0.42264617284854816, 0.45124991230429312, 0.54230307994986526, 1, 1, 1, 1, 1, 1,
    1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, nan, nan, 1, 1, 1,
]
PADJ_EDGE = [0, 1, 0.5, 1e-300, 0.01, 0.01, nan, 1]
PADJ_EDGE_HOLM = [0, 1, 1, 6.0000000000000005e-300, 0.050000000000000003, 0.050000000000000003, nan, 1]
PADJ_EDGE_BH = [
    0, 1, 0.69999999999999996, 3.5000000000000002e-300, 0.017500000000000002, 0.017500000000000002, nan,
    1,
]
HW_MW = dict(U=35, p=0.22067136191984679)
AQ58_MW = dict(U=127.5, p=0.00011637726004353341)
IS_AC_MW = dict(U=143.5, p=3.3815606795784857e-05)
PG_DUNN_A = ["ctrl", "ctrl", "trt1"]
PG_DUNN_B = ["trt1", "trt2", "trt2"]
PG_DUNN_Z = [1.1177254543787873, -1.6892896071861212, -2.8070150615649085]
PG_DUNN_P = [0.26368426789138599, 0.09116394404849984, 0.0050002903702577005]
PG_DUNN_PADJ = [0.26368426789138599, 0.18232788809699968, 0.015000871110773101]
IS_DUNN_A = ["A", "A", "A", "A", "A", "B", "B", "B", "B", "C", "C", "C", "D", "D", "E"]
IS_DUNN_B = ["B", "C", "D", "E", "F", "C", "D", "E", "F", "D", "E", "F", "E", "F", "F"]
IS_DUNN_Z = [
    -0.31273384526703646, 4.7740776066545942, 3.1175655200057637, 3.8505354698503789,
    -0.40557670558068742, 5.0868114519216308, 3.4302993652728002, 4.1632693151174154,
    -0.092842860313651007, -1.6565120866488305, -0.92354213680421515, -5.1796543122352814,
    0.73296994984461539, -3.5231422255864513, -4.2561121754310669,
]
IS_DUNN_P = [
    0.75448287960551608, 1.8053276005508887e-06, 0.0018235140917074899, 0.00011785985881994377,
    0.68505364756428788, 3.6413351689256215e-07, 0.00060291566510473505, 3.1372296669600999e-05,
    0.92602840043271339, 0.097618159426562823, 0.35572475219464628, 2.2229745851851772e-07,
    0.46357675763394141, 0.00042646244245968636, 2.0801237074855786e-05,
]
IS_DUNN_PADJ = [
    1, 2.3469258807161552e-05, 0.012764598641952429, 0.0011785985881994378, 1, 5.0978692364958697e-06,
    0.0048233253208378804, 0.00034509526336561096, 1, 0.58570895655937694, 1, 3.3344618777777657e-06, 1,
    0.0038381619821371772, 0.0002496148448982694,
]
AQ_DUNN_A = ["5", "5", "5", "5", "6", "6", "6", "7", "7", "8"]
AQ_DUNN_B = ["6", "7", "8", "9", "7", "8", "9", "8", "9", "9"]
AQ_DUNN_Z = [
    -0.92515861626872664, -4.4194706406115563, -4.1328134222051123, -1.3212022825201664,
    -2.2442080323946723, -2.0386354872877126, 0.0025385552695226092, 0.28665721840644365,
    3.2171991242773572, 2.9228277777795233,
]
AQ_DUNN_P = [
    0.35488340642579086, 9.8942961500004651e-06, 3.5834961433141897e-05, 0.1864339254627953,
    0.024819019470422133, 0.041486420725049787, 0.99797452811914888, 0.77437479811301979,
    0.0012944872164508631, 0.003468683161149384,
]
AQ_DUNN_PADJ = [
    1, 9.8942961500004644e-05, 0.00032251465289827709, 0.74573570185118121, 0.1489141168225328,
    0.20743210362524894, 1, 1, 0.010355897731606905, 0.024280782128045686,
]
AQ_PKW_H = [
    1.7479519794334482, 17.496598024850339, 14.850499272202718, 2.4622080855033079, 6.114036159223196,
    5.0466252193652315, 0.0047285259425585389, 0.033504799069720495, 11.432276720389233,
    8.7123812869951607,
]
AQ_PKW_P = [
    0.18613440435159104, 2.878222443137908e-05, 0.00011637726004353528, 0.11661474614304655,
    0.013411252442805327, 0.024673950952247187, 0.94517725270077912, 0.85476415249137938,
    0.00072179187451042333, 0.0031605609162546583,
]
AQ_PKW_PADJ = [
    0.55840321305477314, 0.00028782224431379079, 0.0010473953403918174, 0.46645898457218621,
    0.080467514656831968, 0.12336975476123593, 1, 1, 0.0057743349960833867, 0.022123926413782607,
]
IS_PKW_H = [
    0.33714453239518721, 17.190314327485385, 15.84056216057537, 17.423936869793952, 0.65762217359591801,
    17.190314327485385, 16.065580985915499, 17.423936869793952, 0.020979276123754716, 9.2095365022952773,
    3.8721497149714912, 17.401050788091069, 1.9253827497347307, 16.044395604395611, 17.401050788091069,
]
IS_PKW_P = [
    0.56148210753097372, 3.3815606795784674e-05, 6.8909362761065043e-05, 2.9903635581672811e-05,
    0.41740066260456993, 3.3815606795784674e-05, 6.1186083588531137e-05, 2.9903635581672811e-05,
    0.88483542670260862, 0.0024075764092870212, 0.049093602426675528, 3.0265860809414535e-05,
    0.16526448173932459, 6.1874493720818919e-05, 3.0265860809414535e-05,
]
IS_PKW_PADJ = [
    1, 0.00044855453372509216, 0.00055067475229678023, 0.00044855453372509216, 1, 0.00044855453372509216,
    0.00055067475229678023, 0.00044855453372509216, 1, 0.014445458455722128, 0.24546801213337766,
    0.00044855453372509216, 0.66105792695729837, 0.00055067475229678023, 0.00044855453372509216,
]
HW_D = 0.8797172792680098
HW_G = 0.8279692040169504
HW_DZ = 1.0117918052161969
PG_T1_CTRL_D = -0.53274783854321162
PG_T2_CTRL_D = 0.95436295971206087
PG_MW_P = [0.18571128044479951, 0.058781721355358897]


def close(actual, expected, rtol=RTOL):
    """Relative closeness, NaN == NaN, exact zeros compared absolutely."""
    np.testing.assert_allclose(np.asarray(actual, float), np.asarray(expected, float), rtol=rtol, atol=0)


def airquality():
    return pd.DataFrame({"Ozone": AQ_OZONE, "Month": AQ_MONTH})


def insectsprays():
    return pd.DataFrame({"count": IS_COUNT, "spray": IS_SPRAY})


def plantgrowth():
    return pd.DataFrame({"weight": PG_WEIGHT, "group": PG_GROUP})


def groups_of(df, dv, between):
    return [df.loc[df[between] == lev, dv].to_numpy() for lev in sorted(df[between].unique())]


# --- Kruskal-Wallis ------------------------------------------------------------------------------


def test_kruskal_hollander_wolfe_help_example():
    # R: kruskal.test(list(x, y, z)) -> chi-squared = 0.77143, df = 2, p-value = 0.68
    res = analysis.kruskal([2.9, 3.0, 2.5, 2.6, 3.2], [3.8, 2.7, 4.0, 2.4], [2.8, 3.4, 3.7, 2.2, 2.0])
    close(res.H, HW_KW["H"])
    assert res.df == HW_KW["df"] == 2
    close(res.p, HW_KW["p"])
    assert res.N == 14 and res.degenerate is False
    # Published, rounded values of the help page as well.
    assert round(res.H, 5) == 0.77143 and round(res.p, 2) == 0.68


def test_kruskal_airquality_ozone_by_month_drops_na_like_r():
    df = airquality()
    res = analysis.kruskal(*groups_of(df, "Ozone", "Month"))  # NaNs inside the groups
    close(res.H, AQ_KW["H"])
    assert res.df == 4
    close(res.p, AQ_KW["p"])
    assert res.N == 153 - 37  # R's na.omit drops the 37 missing ozone values


def test_kruskal_insectsprays_heavy_ties():
    res = analysis.kruskal(*groups_of(insectsprays(), "count", "spray"))
    close(res.H, IS_KW["H"])
    assert res.df == 5
    close(res.p, IS_KW["p"])


def test_kruskal_plantgrowth():
    res = analysis.kruskal(*groups_of(plantgrowth(), "weight", "group"))
    close(res.H, PG_KW["H"])
    close(res.p, PG_KW["p"])


# --- p.adjust ------------------------------------------------------------------------------------


def test_holm_p_adjust_help_example():
    close(analysis.holm(PADJ_P), PADJ_HOLM)


def test_holm_p_adjust_help_example_with_na():
    out = analysis.holm(PADJ_PN)
    assert np.isnan(out[45]) and np.isnan(out[46])
    assert np.isnan(out).sum() == 2
    close(out, PADJ_HOLM_NA)  # n = 48 non-NA tests, as in R
    # The NAs change the smallest adjusted values (n is 48, not 50): R's point in the example.
    assert out[0] == pytest.approx(PADJ_P[0] * 48, rel=1e-14)


def test_holm_edge_values_match_r():
    # p exactly 0 and 1, a tie, 1e-300 and an NA: p.adjust(c(0, 1, 0.5, 1e-300, 0.01, 0.01, NA, 1), "holm")
    out = analysis.holm(PADJ_EDGE)
    close(out, PADJ_EDGE_HOLM)
    assert out[0] == 0.0 and out[3] > 0.0


def test_other_adjustments_match_r():
    close(analysis.adjust_pvalues(PADJ_P, "fdr_bh"), PADJ_BH)
    close(analysis.adjust_pvalues(PADJ_P, "bonferroni"), PADJ_BONF)
    close(analysis.adjust_pvalues(PADJ_PN, "bh"), PADJ_BH_NA)
    close(analysis.adjust_pvalues(PADJ_PN, "bonferroni"), PADJ_BONF_NA)
    close(analysis.adjust_pvalues(PADJ_EDGE, "BH"), PADJ_EDGE_BH)


# --- Mann-Whitney --------------------------------------------------------------------------------


def test_mann_whitney_hollander_wolfe_two_sample_example():
    x = [0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46]
    y = [1.15, 0.88, 0.90, 0.74, 1.21]
    res = analysis.mann_whitney(x, y)
    assert res.U == HW_MW["U"] == 35
    close(res.p, HW_MW["p"])
    assert (res.n_x, res.n_y) == (10, 5)


def test_mann_whitney_airquality_may_vs_august_with_ties_and_na():
    df = airquality()
    res = analysis.mann_whitney(df.Ozone[df.Month == 5], df.Ozone[df.Month == 8])
    assert res.U == AQ58_MW["U"]
    close(res.p, AQ58_MW["p"])
    assert res.z < 0  # May ozone is lower


def test_mann_whitney_insectsprays_a_vs_c():
    df = insectsprays()
    res = analysis.mann_whitney(df["count"][df.spray == "A"], df["count"][df.spray == "C"])
    assert res.U == IS_AC_MW["U"]
    close(res.p, IS_AC_MW["p"])


# --- Dunn ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "frame, dv, between, prefix",
    [
        (plantgrowth, "weight", "group", "PG"),
        (insectsprays, "count", "spray", "IS"),
        (airquality, "Ozone", "Month", "AQ"),
    ],
)
@pytest.mark.parametrize("source, z_sign", [("DUNN", 1.0), ("RSTATIX", -1.0)])
def test_dunn_matches_r(frame, dv, between, prefix, source, z_sign):
    """Against the by-hand formula (DUNN) and rstatix::dunn_test (RSTATIX, z = group2 - group1)."""
    ref = {k: globals()[f"{prefix}_{source}_{k}"] for k in ("A", "B", "Z", "P", "PADJ")}
    out = analysis.dunn(frame(), dv, between)
    assert list(out.columns) == ["A", "B", "z", "p_unc", "p_adj", "note"]
    assert [str(a) for a in out.A] == ref["A"] and [str(b) for b in out.B] == ref["B"]
    close(z_sign * out.z, ref["Z"])
    close(out.p_unc, ref["P"])
    close(out.p_adj, ref["PADJ"])


# --- pairwise Kruskal-Wallis ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "frame, dv, between, prefix",
    [(airquality, "Ozone", "Month", "AQ"), (insectsprays, "count", "spray", "IS")],
)
def test_pairwise_kruskal_matches_r(frame, dv, between, prefix):
    out = analysis.pairwise_kruskal(frame(), dv, between)
    assert list(out.columns) == ["A", "B", "H", "df", "p_unc", "p_adj", "n_A", "n_B", "note"]
    close(out.H, globals()[f"{prefix}_PKW_H"])
    close(out.p_unc, globals()[f"{prefix}_PKW_P"])
    close(out.p_adj, globals()[f"{prefix}_PKW_PADJ"])
    assert (out.df == 1).all()


def test_pairwise_kruskal_airquality_sizes_and_matrix():
    out = analysis.pairwise_kruskal(airquality(), "Ozone", "Month")
    first = out.iloc[0]
    assert (first.A, first.B, first.n_A, first.n_B) == (5, 6, 26, 9)  # June has only 9 ozone values
    m = analysis.pairwise_matrix(out, order=[5, 6, 7, 8, 9])
    # Rounded R values: p.adjust(...)[c(1, 2, 3, 10)] = 0.5584, 0.000288, 0.00105, 0.0221
    assert m.loc[5, 6] == "0.558"
    assert m.loc[5, 7] == "<0.001"
    assert m.loc[5, 8] == "0.001"
    assert m.loc[8, 9] == "0.022"
    assert m.loc[7, 8] == "1.000"
    assert m.loc[6, 5] == "/" and m.loc[9, 9] == "/"


# --- effect sizes (by-hand R formulas) -----------------------------------------------------------


def test_cohens_d_and_hedges_g_match_r_by_hand():
    x = [0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46]
    y = [1.15, 0.88, 0.90, 0.74, 1.21]
    close(analysis.cohens_d(x, y), HW_D)
    close(analysis.hedges_g(x, y), HW_G)
    close(analysis.cohens_d(y, x), -HW_D)


def test_paired_dz_matches_r_by_hand():
    # Hollander & Wolfe (1973, p. 29f) depression data from the wilcox.test help page.
    x = [1.83, 0.50, 1.62, 2.48, 1.68, 1.88, 1.55, 3.06, 1.30]
    y = [0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.14, 1.29]
    close(analysis.cohens_d(x, y, paired=True), HW_DZ)


def test_summary_table_plantgrowth_matches_r():
    out = analysis.summary_table(plantgrowth(), "weight", "group", reference="ctrl")
    assert list(out.condition) == ["trt1", "trt2"]
    close(out["mean"], [4.661, 5.526], rtol=1e-13)  # R: tapply(weight, group, mean)
    close(out["std"], [0.79367569643470326, 0.44257328332278606])  # R: tapply(weight, group, sd)
    close(out["mean_ref"], [5.032, 5.032], rtol=1e-13)
    close(out["std_ref"], [0.58309137839240566] * 2)
    close(out["p"], [0.18571128044479951, 0.058781721355358897])  # wilcox.test(exact=F, correct=F)
    close(out["d"], [PG_T1_CTRL_D, PG_T2_CTRL_D])
    assert list(out.label) == ["medium", "large"]  # |d| = 0.53 and 0.95


def test_r_version_recorded():
    assert R_VERSION.startswith("R version 4.2.2")
    assert math.isclose(HW_KW["H"], 27 / 35, rel_tol=1e-14)  # exact value of the H&W example

# --- Dunn against a published implementation: rstatix::dunn_test ---------------------------------------------
# rstatix 0.7.2 (Debian r-cran-rstatix; installed by hand only to print these constants; CRAN, and with it
# FSA and dunn.test, is not reachable here). Script (Rscript), datasets as above:
#   r <- as.data.frame(rstatix::dunn_test(PlantGrowth, weight ~ group, p.adjust.method = "holm"))
#   (likewise InsectSprays count ~ spray, airquality Ozone ~ factor(Month) without NA ozone)
#   sprintf("%.17g", r$statistic), r$p, r$p.adj
# rstatix reports z as group2 minus group1, the opposite sign of FSA::dunnTest and of analysis.dunn (A - B);
# test_dunn_matches_r checks both sources.
PG_RSTATIX_A = ['ctrl', 'ctrl', 'trt1']
PG_RSTATIX_B = ['trt1', 'trt2', 'trt2']
PG_RSTATIX_Z = [-1.1177254543787873, 1.6892896071861212, 2.8070150615649085]
PG_RSTATIX_P = [0.26368426789138599, 0.09116394404849984, 0.0050002903702577005]
PG_RSTATIX_PADJ = [0.26368426789138599, 0.18232788809699968, 0.015000871110773101]
IS_RSTATIX_A = ['A', 'A', 'A', 'A', 'A', 'B', 'B', 'B', 'B', 'C', 'C', 'C', 'D', 'D', 'E']
IS_RSTATIX_B = ['B', 'C', 'D', 'E', 'F', 'C', 'D', 'E', 'F', 'D', 'E', 'F', 'E', 'F', 'F']
IS_RSTATIX_Z = [0.31273384526703646, -4.7740776066545942, -3.1175655200057637, -3.8505354698503789, 0.40557670558068742, -5.0868114519216308, -3.4302993652728002, -4.1632693151174154, 0.092842860313651007, 1.6565120866488305, 0.92354213680421515, 5.1796543122352814, -0.73296994984461539, 3.5231422255864513, 4.2561121754310669]
IS_RSTATIX_P = [0.75448287960551608, 1.8053276005508887e-06, 0.0018235140917074899, 0.00011785985881994377, 0.68505364756428788, 3.6413351689256215e-07, 0.00060291566510473505, 3.1372296669600999e-05, 0.92602840043271339, 0.097618159426562823, 0.35572475219464628, 2.2229745851851772e-07, 0.46357675763394141, 0.00042646244245968636, 2.0801237074855786e-05]
IS_RSTATIX_PADJ = [1.0, 2.3469258807161552e-05, 0.012764598641952429, 0.0011785985881994378, 1.0, 5.0978692364958697e-06, 0.0048233253208378804, 0.00034509526336561096, 1.0, 0.58570895655937694, 1.0, 3.3344618777777657e-06, 1.0, 0.0038381619821371772, 0.0002496148448982694]
AQ_RSTATIX_A = ['5', '5', '5', '5', '6', '6', '6', '7', '7', '8']
AQ_RSTATIX_B = ['6', '7', '8', '9', '7', '8', '9', '8', '9', '9']
AQ_RSTATIX_Z = [0.92515861626872664, 4.4194706406115563, 4.1328134222051123, 1.3212022825201664, 2.2442080323946723, 2.0386354872877126, -0.0025385552695226092, -0.28665721840644365, -3.2171991242773572, -2.9228277777795233]
AQ_RSTATIX_P = [0.35488340642579086, 9.8942961500004651e-06, 3.5834961433141897e-05, 0.1864339254627953, 0.024819019470422133, 0.041486420725049787, 0.99797452811914888, 0.77437479811301979, 0.0012944872164508631, 0.003468683161149384]
AQ_RSTATIX_PADJ = [1.0, 9.8942961500004644e-05, 0.00032251465289827709, 0.74573570185118121, 0.1489141168225328, 0.20743210362524894, 1.0, 1, 0.010355897731606905, 0.024280782128045686]
