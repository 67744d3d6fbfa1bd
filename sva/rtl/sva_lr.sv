// The SVA's single-pass left-right check, as the chip plan describes the stage
// (sim/cycle/stages.py: sva_stages, "lr_check": latency (D - 1) II + 1, the diagonal through the
// next D - 1 pixels; the words are sva/lr_check.py's definition: dR(x_r) the smallest d with
// x_r + d < W minimising S(x_r + d, d); a left word with winner d* stays when x - d* >= 0 and
// |d* - dR(x - d*)| <= max_diff, else it becomes -1).
//
// Interface (a stage of the lock-step pipeline; every register moves only in a tick, en = 1):
//   in_valid, s_in, q_in, d_in   a left pixel's D summed costs S(x, d), its word and its
//                    winner d*, in raster order; within a row a pixel every II ticks, a row's
//                    first pixel k II ticks after the previous row's last (k >= 1) or once
//                    that row has drained (D - 1 II ticks after its last pixel);
//   width, ii, max_diff   run-time registers: the frame's W, the pipeline's II, the largest
//                    |d* - dR| accepted;
//   out_valid, q_out the checked word of the pixel that arrived (D - 1) II + 1 ticks before.
//
// Structure (the cycles come from it):
// - the window shifts one pixel at each arriving pixel and, after a row's last pixel, D - 1
//   times more, one every II ticks (the row's drain: nothing arrives beyond x = W - 1);
// - right pixels x .. x - D + 2 in D - 1 registers of (best cost, its d): at a shift the new
//   pixel x's S(x, d) competes (strict <: the smallest d on ties) in the register of right
//   pixel x - d for d <= x; right pixel x - D + 1 takes its last candidate S(x, D - 1) and is
//   complete: its dR goes into a shift register of the D - 1 dRs completed before;
// - the left words x .. x - D + 2 wait in D - 1 registers (with x - d* >= 0); at a shift the
//   word of x - D + 1 reads dR(x - D + 1 - d*) (the one completing now or the shift register)
//   and the output register takes it checked.
// So a pixel's word leaves D - 1 shifts after it arrived, plus the output register: (D - 1) II
// + 1 ticks when the shifts are II apart.
module sva_lr #(
    parameter int D = 16,       // disparities
    parameter int SW = 12,      // bits of a summed cost S
    parameter int DB = 4,       // bits of d (bits_for(D - 1))
    parameter int WB = 9,       // bits of a word (two's complement, -1 invalid)
    parameter int XW = 8        // bits of a column
) (
    input  logic              clk,
    input  logic              rst,
    input  logic              en,
    input  logic              in_valid,
    input  logic [D*SW-1:0]   s_in,
    input  logic [WB-1:0]     q_in,
    input  logic [DB-1:0]     d_in,
    input  logic [XW-1:0]     width,
    input  logic [7:0]        ii,
    input  logic [7:0]        max_diff,
    output logic              out_valid,
    output logic [WB-1:0]     q_out
);
  localparam int R = D - 1;     // registers of each chain

  logic [XW-1:0] xc;            // the arriving pixel's column
  logic [DB:0]   drain;         // shifts left of the row's drain
  logic [7:0]    phase;         // ticks since the last shift
  logic          shift;
  assign shift = en && (in_valid || (drain != '0 && phase == ii - 8'd1));

  logic [SW-1:0] rb [R];        // right pixel xc - 1 - i: best cost (before this shift)
  logic [DB-1:0] rd [R];        //   and its d
  logic [DB-1:0] hd [R];        // hd[j]: dR of the right pixel completed j + 1 shifts ago
  logic [WB-1:0] lq [R];        // left pixel xc - 1 - i: its word,
  logic [DB-1:0] ld [R];        //   d*,
  logic          lok [R];       //   x - d* >= 0,
  logic          lv [R];        //   and whether it holds a word (not a drain bubble)

  // the shift: each right register takes its new candidate, the last completes
  logic [SW-1:0] nb [R+1];      // after the shift: right pixel x - i (i = R: complete)
  logic [DB-1:0] nd [R+1];
  always_comb begin
    nb[0] = s_in[0 +: SW];
    nd[0] = '0;
    for (int i = 1; i <= R; i++) begin
      logic [SW-1:0] cand;
      cand = s_in[i*SW +: SW];
      if (in_valid && i <= int'(xc) && cand < rb[i-1]) begin
        nb[i] = cand; nd[i] = DB'(i);
      end else begin
        nb[i] = rb[i-1]; nd[i] = rd[i-1];
      end
    end
  end

  // the word leaving: left pixel x - D + 1, checked against dR(x - D + 1 - d*)
  logic [DB-1:0] dr_of;
  logic [DB:0]   diff;
  logic          keep;
  always_comb begin
    int j;
    j = int'(ld[R-1]);
    dr_of = (j == 0) ? nd[R] : hd[j-1];
    diff = (ld[R-1] >= dr_of) ? (DB+1)'(ld[R-1] - dr_of) : (DB+1)'(dr_of - ld[R-1]);
    keep = lok[R-1] && (9'(diff) <= {1'b0, max_diff});
  end

  always_ff @(posedge clk) begin
    if (rst) begin
      xc <= '0; drain <= '0; phase <= '0; out_valid <= 1'b0;
      for (int i = 0; i < R; i++) lv[i] <= 1'b0;
    end else if (en) begin
      out_valid <= 1'b0;
      phase <= shift ? 8'd0 : ((phase == 8'hff) ? phase : phase + 8'd1);
      if (shift) begin
        for (int i = 0; i < R; i++) begin
          rb[i] <= nb[i]; rd[i] <= nd[i];
        end
        hd[0] <= nd[R];
        for (int j = 1; j < R; j++) hd[j] <= hd[j-1];
        lq[0] <= q_in; ld[0] <= d_in; lok[0] <= in_valid && (int'(d_in) <= int'(xc));
        lv[0] <= in_valid;
        for (int i = 1; i < R; i++) begin
          lq[i] <= lq[i-1]; ld[i] <= ld[i-1]; lok[i] <= lok[i-1]; lv[i] <= lv[i-1];
        end
        out_valid <= lv[R-1];
        q_out <= keep ? lq[R-1] : '1;
        if (in_valid) begin
          xc <= (xc == width - 1'b1) ? '0 : xc + 1'b1;
          drain <= (xc == width - 1'b1) ? (DB+1)'(R) : ((drain != '0) ? drain - 1'b1 : '0);
        end else begin
          drain <= drain - 1'b1;
        end
      end
    end
  end
endmodule
