// The SVA's disparity selection: winner-take-all, the uniqueness check and the sub-pixel step,
// as the chip plan describes the stage (sva/wta/timing.py: wta_stage, "wta"; the words are
// sva/wta/wta.py's definition: d* the first index of the minimum, S2 the minimum over |d - d*| >= 2,
// o = floor((2 num + den) / (2 den)) with num = (a - b) 2^F).
//
// Interface (a stage of the lock-step pipeline; every register moves only in a cycle with
// en = 1, the pipeline's tick):
//   in_valid, s_in    a pixel's D summed costs S(d) (s_in[d*SW +: SW]), taken in a tick with
//                     in_valid && in_ready; in_ready: the stage is free (its II: a pixel
//                     every G ticks);
//   uniq, mode        run-time registers: the uniqueness margin u (percent, 0: off) and the
//                     sub-pixel fit (0 off, 1 parabola, 2 equiangular); both hold over a frame;
//   out_valid, q      the output word (WB = 1 + DB + F bits, two's complement: -1 invalid,
//                     else (d* << F) + o), with d* (dstar) and S1 = S(d*) (s1) for the
//                     stages after it (the LR check).
//
// Structure (the cycles come from it, no delay register is added to meet a number):
// - an input register takes the pixel; in the G = ceil(D / LANES) ticks after, lane group k
//   (d = k LANES .. k LANES + LANES - 1) enters a tree of two-input merge nodes over its
//   LANES costs, lg(LANES) levels; with G > 1 one more level folds the group into the running
//   node of the earlier groups (its register is the loop's). A node over an index range holds
//   the minimum and its first index, and -- for the uniqueness and the sub-pixel step -- the
//   minimum over its range at |d - i| >= 2 (f), the minimum without its first / last element,
//   its first and last value and the winner's two neighbours' values: one compare level (the
//   minima, side by side) and selects, so S2 and S(d* -+ 1) leave the tree with S1 and d*;
// - V merge levels settle in one tick: a pipeline register after every V levels, the running
//   (or result) register after the last: T = ceil((lg(LANES) + [G > 1]) / V) ticks;
// - uniqueness (u > 0): one tick, S2 100 < S1 (100 + u) invalidates the word; u = 0 bypasses it;
// - sub-pixel (mode != 0): a divider of F + 1 ticks, one quotient bit a tick: the
//   numerator (2 num + den) + 2^(F-1) 2 den >= 0 over 2 den gives o + 2^(F-1) in F + 1 bits
//   (|o| <= 2^(F-1)), the first tick also forms den and the numerator, the last the word;
//   mode 0 bypasses it.
// So a pixel taken in tick t0 leaves in tick t0 + G + T + [u > 0] + (F + 1) [mode != 0].
// The plan's rule (sva/wta/timing.py) is this structure's since this twin showed its earlier
// G + tree(lg(D)) + [uniq] + sub a tick long with G > 2 (tests/rtl/test_sva_wta_lr_median.py).
module sva_wta #(
    parameter int D = 16,       // disparities
    parameter int LANES = 16,   // disparities a tick
    parameter int V = 8,        // merge levels that settle in one tick
    parameter int SW = 12,      // bits of a summed cost S
    parameter int F = 4,        // fractional bits of the word (>= 0)
    parameter int DB = 4,       // bits of d* (bits_for(D - 1))
    parameter int WB = 1 + DB + F  // the output word
) (
    input  logic              clk,
    input  logic              rst,
    input  logic              en,
    input  logic              in_valid,
    output logic              in_ready,
    input  logic [D*SW-1:0]   s_in,
    input  logic [6:0]        uniq,
    input  logic [1:0]        mode,
    output logic              out_valid,
    output logic [WB-1:0]     q,
    output logic [DB-1:0]     dstar,
    output logic [SW-1:0]     s1
);
  localparam int G = (D + LANES - 1) / LANES;
  localparam int LG = (LANES > 1) ? $clog2(LANES) : 0;
  localparam int N = 1 << LG;                       // leaves, padded to a power of two
  localparam int LEVELS = LG + ((G > 1) ? 1 : 0);   // + the fold
  localparam int T = (LEVELS + V - 1) / V;          // ticks through the tree
  localparam int GW = (G > 1) ? $clog2(G) : 1;
  localparam int IW = $clog2(G * N) + 1;            // an index (absolute, with the padding)
  localparam int VW = SW + 1;                       // a value; INF = 2^SW: none
  localparam logic [VW-1:0] INF = VW'(1) << SW;
  // a node: m, f, xf, xl, a, b, lov, hiv (VW bits each), then i
  localparam int NW = 8 * VW + IW;

  function automatic logic [VW-1:0] vmin(input logic [VW-1:0] x, input logic [VW-1:0] y);
    vmin = (x <= y) ? x : y;
  endfunction

  // field k of node n: n[k*VW +: VW]; the index: n[8*VW +: IW]
  function automatic logic [NW-1:0] leaf(input logic [VW-1:0] v, input logic [IW-1:0] i);
    leaf = {i, v, v, INF, INF, INF, INF, INF, v};  // i | hiv lov b a xl xf f m
  endfunction

  // merge A (the lower indices) and B: a_hi, A's winner is A's last element; b_lo, B's winner
  // is B's first element
  function automatic logic [NW-1:0] merge(input logic [NW-1:0] A, input logic [NW-1:0] B,
                                          input logic a_hi, input logic b_lo);
    logic [VW-1:0] am, af, axf, axl, aa, ab, alo, ahi;
    logic [VW-1:0] bm, bf, bxf, bxl, ba, bb, blo, bhi;
    logic [VW-1:0] m, f, xf, xl, a, b;
    logic [IW-1:0] i;
    {ahi, alo, ab, aa, axl, axf, af, am} = A[8*VW-1:0];
    {bhi, blo, bb, ba, bxl, bxf, bf, bm} = B[8*VW-1:0];
    xf = vmin(axf, bm);
    xl = vmin(am, bxl);
    if (am <= bm) begin
      m = am; i = A[8*VW +: IW]; a = aa;
      b = a_hi ? blo : ab;
      f = vmin(af, a_hi ? bxf : bm);
    end else begin
      m = bm; i = B[8*VW +: IW]; b = bb;
      a = b_lo ? ahi : ba;
      f = vmin(bf, b_lo ? axl : am);
    end
    merge = {i, bhi, alo, b, a, xl, xf, f, m};
  endfunction

  // ---- the input register and the lane-group counter --------------------------------------
  logic [D*SW-1:0] s_q;
  logic [GW-1:0]   group;
  logic            busy;
  assign in_ready = !busy || (group == GW'(G - 1));
  always_ff @(posedge clk) begin
    if (rst) begin
      busy <= 1'b0;
      group <= '0;
    end else if (en) begin
      if (busy) group <= (group == GW'(G - 1)) ? '0 : group + 1'b1;
      if (in_valid && in_ready) begin
        s_q <= s_in;
        busy <= 1'b1;
      end else if (busy && group == GW'(G - 1)) begin
        busy <= 1'b0;
      end
    end
  end

  // ---- the lane group's tree: level l node k over lanes [k 2^l, (k + 1) 2^l) --------------
  // lvl[l].n[k]: node k after level l (after the register, where level l ends a tick)
  genvar l, k;
  generate
    for (l = 0; l <= LG; l++) begin : lvl
      localparam int NODES = N >> l;
      localparam int SPAN = 1 << l;
      localparam bit REG = (l > 0) && (l < LEVELS) && (l % V == 0);
      logic [NW-1:0] c [NODES];
      logic [NW-1:0] n [NODES];
      logic [GW-1:0] cg, ng;
      logic          cv, nv;
      if (l == 0) begin : leaves
        for (k = 0; k < N; k++) begin : lf
          always_comb begin
            int di;
            di = int'(group) * LANES + k;
            if (k < LANES && di < D)
              c[k] = leaf({1'b0, s_q[di*SW +: SW]}, IW'(k));
            else
              c[k] = leaf(INF, IW'(k));
          end
        end
        assign cg = group;
        assign cv = busy;
      end else begin : node
        for (k = 0; k < NODES; k++) begin : mg
          localparam int LO_B = (2 * k + 1) * (SPAN / 2);  // B's first lane
          if (LO_B >= LANES) begin : only_a                 // B lies in the padding
            assign c[k] = lvl[l-1].n[2*k];
          end else begin : both
            logic [NW-1:0] A, B;
            assign A = lvl[l-1].n[2*k];
            assign B = lvl[l-1].n[2*k+1];
            assign c[k] = merge(A, B, A[8*VW +: IW] == IW'(LO_B - 1),
                                B[8*VW +: IW] == IW'(LO_B));
          end
        end
        assign cg = lvl[l-1].ng;
        assign cv = lvl[l-1].nv;
      end
      if (REG) begin : pipe
        always_ff @(posedge clk) begin
          if (en) begin
            n <= c; ng <= cg;
          end
          if (rst) nv <= 1'b0; else if (en) nv <= cv;
        end
      end else begin : wire_
        assign n = c; assign ng = cg; assign nv = cv;
      end
    end
  endgenerate

  // ---- the fold (G > 1) and the result register ------------------------------------------
  logic [NW-1:0] group_node;   // the group's winner, its index made absolute
  logic [GW-1:0] tail_group;
  logic          tail_valid;
  always_comb begin
    group_node = lvl[LG].n[0];
    tail_group = lvl[LG].ng;
    tail_valid = lvl[LG].nv;
    group_node[8*VW +: IW] = IW'(int'(tail_group) * LANES) + lvl[LG].n[0][8*VW +: IW];
  end
  logic [NW-1:0] run_q;        // the running node of the pixel's groups so far
  logic          res_valid;    // run_q holds a whole pixel's result
  logic [NW-1:0] next_run;
  always_comb begin
    if (G == 1 || tail_group == '0) begin
      next_run = group_node;
    end else begin
      next_run = merge(run_q, group_node,
                       run_q[8*VW +: IW] == IW'(int'(tail_group) * LANES - 1),
                       group_node[8*VW +: IW] == IW'(int'(tail_group) * LANES));
    end
  end
  always_ff @(posedge clk) begin
    if (rst) begin
      res_valid <= 1'b0;
    end else if (en) begin
      if (tail_valid) run_q <= next_run;
      res_valid <= tail_valid && (tail_group == GW'(G - 1));
    end
  end
  // the result's fields
  logic [VW-1:0] r_m, r_f, r_a, r_b;
  logic [IW-1:0] r_i;
  assign r_m = run_q[0 +: VW];
  assign r_f = run_q[VW +: VW];
  assign r_a = run_q[4*VW +: VW];
  assign r_b = run_q[5*VW +: VW];
  assign r_i = run_q[8*VW +: IW];

  // ---- uniqueness: one tick, or bypassed (u = 0) ------------------------------------------
  // the pixel as it goes on: valid (a pixel), ok (not rejected), d*, S1, a, b
  localparam int PW = 2 + DB + 3 * VW;
  logic [PW-1:0] p_res, p_uniq, p_u;
  assign p_res = {res_valid, 1'b1, r_i[DB-1:0], r_m, r_a, r_b};
  logic [SW+8:0] lhs, rhs;
  assign lhs = (SW+9)'(r_f) * (SW+9)'(100);
  assign rhs = (SW+9)'(r_m) * (SW+9)'(100 + int'(uniq));
  always_ff @(posedge clk) begin
    if (en) p_uniq <= {res_valid, r_f[SW] || !(lhs < rhs), r_i[DB-1:0], r_m, r_a, r_b};
    if (rst) p_uniq[PW-1] <= 1'b0;
  end
  assign p_u = (uniq != 7'd0) ? p_uniq : p_res;

  // ---- sub-pixel: F + 1 ticks of one quotient bit each, or bypassed (mode 0) ---------------
  localparam int RW = SW + F + 6;   // the remainder (>= 0), the divisor shifted
  localparam int QW = F + 1;        // o + 2^(F-1) in 0 .. 2^F
  // step 0's input: den and the numerator from the pixel
  logic          fit0;
  logic [RW-1:0] r0, m0;
  always_comb begin
    logic signed [RW:0] a, b, c, den, num;
    logic [DB-1:0] di;
    a = (RW+1)'(p_u[VW +: VW]);
    b = (RW+1)'(p_u[0 +: VW]);
    c = (RW+1)'(p_u[2*VW +: VW]);
    di = p_u[3*VW +: DB];
    if (mode == 2'd1) den = 2 * (a + b - 2 * c);
    else den = 2 * ((a - c > b - c) ? a - c : b - c);
    num = ((a - b) <<< (F + 1)) + den + (den <<< F);
    fit0 = (F > 0) && (mode != 2'd0) && (di != '0) && (int'(di) != D - 1) && (den > 0);
    r0 = RW'(num);
    m0 = RW'(2 * den);
  end
  genvar j;
  generate
    for (j = 0; j <= F; j++) begin : step
      localparam int BIT = F - j;
      logic [PW-1:0] ip, p;      // the pixel at the step's input, in its register
      logic          ifit, fit;
      logic [RW-1:0] ir, im, r, m, sub_m;
      logic [QW-1:0] iq, qb;
      logic          take;
      if (j == 0) begin : first
        assign ip = p_u; assign ifit = fit0; assign ir = r0; assign im = m0; assign iq = '0;
      end else begin : next
        assign ip = step[j-1].p; assign ifit = step[j-1].fit; assign ir = step[j-1].r;
        assign im = step[j-1].m; assign iq = step[j-1].qb;
      end
      assign sub_m = im << BIT;
      assign take = ir >= sub_m;
      always_ff @(posedge clk) begin
        if (en) begin
          p <= ip; fit <= ifit; m <= im;
          r <= take ? ir - sub_m : ir;
          qb <= iq | (QW'(take) << BIT);
        end
        if (rst) p[PW-1] <= 1'b0;
      end
    end
  endgenerate

  // ---- the word ---------------------------------------------------------------------------
  logic [PW-1:0] p_out;
  logic          fit_out;
  logic [QW-1:0] q_out;
  assign p_out = (mode != 2'd0) ? step[F].p : p_u;
  assign fit_out = (mode != 2'd0) ? step[F].fit : 1'b0;
  assign q_out = step[F].qb;
  always_comb begin
    logic signed [WB:0] o, word;
    o = fit_out ? ((WB+1)'(q_out) - (WB+1)'((1 << F) >> 1)) : '0;
    word = ((WB+1)'(p_out[3*VW +: DB]) <<< F) + o;
    out_valid = p_out[PW-1];
    q = p_out[PW-2] ? word[WB-1:0] : '1;
    dstar = p_out[3*VW +: DB];
    s1 = p_out[2*VW +: SW];
  end
endmodule
