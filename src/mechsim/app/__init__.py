"""The application layer, on top of everything: scene files (`scene`, `scene_build`), study
files (`study_file`), the `mechsim` command (`cli`), benchmarks (`bench`, `bench_analysis`,
`costs`, `peers`) and reading saved results back with their mechanism (`loading`). Nothing
below imports it."""
