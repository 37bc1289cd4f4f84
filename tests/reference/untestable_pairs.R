# R 4.2.2 reference values for pairs whose observations are all tied (tests/test_analysis_degenerate.py).
# Run: Rscript tests/reference/untestable_pairs.R
s <- function(v) paste0("[", paste(ifelse(is.na(v), "nan", sprintf("%.17g", v)), collapse = ", "), "]")
pairwise_kw <- function(groups) {  # kruskal.test on each pair's subset, then p.adjust(holm)
  pr <- combn(length(groups), 2)
  p <- apply(pr, 2, function(ij) kruskal.test(list(groups[[ij[1]]], groups[[ij[2]]]))$p.value)
  list(p = p, holm = p.adjust(p, "holm"))
}
dunn <- function(groups) {  # Dunn's z, two-sided p, Holm across the pairs (NA where the pair is all tied)
  y <- unlist(groups); g <- rep(seq_along(groups), lengths(groups)); N <- length(y)
  r <- rank(y); t <- table(y); s2 <- N * (N + 1) / 12 - sum(t^3 - t) / (12 * (N - 1))
  pr <- combn(length(groups), 2)
  z <- apply(pr, 2, function(ij) {
    a <- groups[[ij[1]]]; b <- groups[[ij[2]]]
    if (length(unique(c(a, b))) == 1) return(NA)
    (mean(r[g == ij[1]]) - mean(r[g == ij[2]])) / sqrt(s2 * (1 / length(a) + 1 / length(b)))
  })
  p <- 2 * pnorm(-abs(z))
  list(z = z, p = p, holm = p.adjust(p, "holm"))
}
cat("R_VERSION =", shQuote(R.version.string, type = "cmd"), "\n")
# 1. the issue's example: a = b = [1, 1, 1], c = [2, 3, 4]
g1 <- list(a = c(1, 1, 1), b = c(1, 1, 1), c = c(2, 3, 4))
k <- pairwise_kw(g1); d <- dunn(g1)
cat("ABC_PKW_P =", s(k$p), "\nABC_PKW_HOLM =", s(k$holm), "\n")
cat("ABC_DUNN_Z =", s(d$z), "\nABC_DUNN_P =", s(d$p), "\nABC_DUNN_HOLM =", s(d$holm), "\n")
# 2. five conditions of 0/1-like scores, two of them constant at 1 and one constant at 0
g2 <- list(A = c(1, 1, 1, 1), B = c(1, 1, 1), C = c(0, 1, 1, 0, 1), D = c(0, 0, 0, 0), E = c(0, 1, 0, 0, 0, 1))
k <- pairwise_kw(g2); d <- dunn(g2)
cat("FIVE_PKW_P =", s(k$p), "\nFIVE_PKW_HOLM =", s(k$holm), "\n")
cat("FIVE_DUNN_Z =", s(d$z), "\nFIVE_DUNN_P =", s(d$p), "\nFIVE_DUNN_HOLM =", s(d$holm), "\n")
# 3. wilcox.test of two identical constant groups, and Cohen's d by R's formula (0/0 and 1/0)
w <- wilcox.test(c(4, 4, 4), c(4, 4, 4), exact = FALSE, correct = FALSE)$p.value
d0 <- function(x, y) (mean(x) - mean(y)) / sqrt(((length(x) - 1) * var(x) + (length(y) - 1) * var(y)) /
                                              (length(x) + length(y) - 2))
cat("TIED_WILCOX_P =", s(w), "\nD_SAME_CONST =", s(d0(c(4, 4, 4), c(4, 4, 4))),
    "\nD_DIFF_CONST =", s(d0(c(1, 1), c(2, 2))), "\nD_ONE_EACH =", s(d0(1, 2)), "\n")
