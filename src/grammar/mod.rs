//! The stochastic, attributed shape grammar of seed 003 §3.3: parser, interpreter, shape tree.
