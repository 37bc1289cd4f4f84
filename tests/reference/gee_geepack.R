# geepack::geeglm reference values for tests/test_analysis_gee.py.
# Usage: Rscript gee_geepack.R DIR   (DIR holds the CSVs written by gee_geepack.py; run that script instead)
# Each CSV: participant, condition, y, with the first line of a companion .txt naming the reference and
# whether the model has an intercept. geeglm's default scale (estimated) matches statsmodels' ddof_scale=0.
suppressMessages(library(geepack))
s <- function(v) paste0("[", paste(sprintf("%.17g", v), collapse = ", "), "]")
dir <- commandArgs(trailingOnly = TRUE)[1]
cat("GEEPACK_VERSION =", shQuote(as.character(packageVersion("geepack")), type = "cmd"), "\n")
cat("R_VERSION =", shQuote(R.version.string, type = "cmd"), "\n")
cat("GEEPACK = {\n")
for (f in sort(list.files(dir, pattern = "\\.csv$", full.names = TRUE))) {
  spec <- strsplit(readLines(sub("\\.csv$", ".txt", f))[1], " ")[[1]]
  d <- read.csv(f, stringsAsFactors = FALSE)
  d$pid <- as.integer(factor(d$participant))
  d <- d[order(d$pid), ]  # geeglm needs each cluster's rows together
  d$condition <- factor(d$condition)
  if (spec[2] == "intercept") d$condition <- relevel(d$condition, ref = spec[1])
  form <- if (spec[2] == "intercept") y ~ condition else y ~ 0 + condition
  g <- geeglm(form, id = pid, data = d, family = binomial, corstr = "exchangeable",
              control = geese.control(epsilon = 1e-12, maxit = 200))
  co <- summary(g)$coefficients
  cat(sprintf("    %s: dict(terms=%s, coef=%s, se=%s, alpha=%s),\n", shQuote(basename(f), type = "cmd"),
              paste0("[", paste(shQuote(rownames(co), type = "cmd"), collapse = ", "), "]"),
              s(co[, "Estimate"]), s(co[, "Std.err"]), s(g$geese$alpha)))
}
cat("}\n")
